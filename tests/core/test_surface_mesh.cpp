// Surface facts on meshes whose answer is known by construction.

#include "core/adjacency.h"
#include "core/errors.h"
#include "core/surface_mesh.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace scalemesh {
namespace {

SurfaceMesh octahedron(double r = 1.0, Vec3 c = {})
{
    SurfaceMesh m;
    m.points = {c + Vec3{r, 0, 0}, c + Vec3{-r, 0, 0}, c + Vec3{0, r, 0},
                c + Vec3{0, -r, 0}, c + Vec3{0, 0, r}, c + Vec3{0, 0, -r}};
    m.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    return m;
}

TEST(SurfaceFacts, OctahedronIsAClosedSphereWithItsVolume)
{
    const SurfaceFacts f = surface_facts(octahedron(2.0));
    EXPECT_TRUE(f.closed_manifold());
    EXPECT_EQ(f.vertices, 6);
    EXPECT_EQ(f.edges, 12);
    EXPECT_EQ(f.euler_characteristic, 2);
    EXPECT_EQ(f.components, 1);
    EXPECT_NEAR(f.signed_volume, 4.0 / 3.0 * 8.0, 1e-12); // 4/3 r^3
}

TEST(SurfaceFacts, DetectsHolesFlipsAndPinchedVertices)
{
    SurfaceMesh open = octahedron();
    open.triangles.pop_back();
    EXPECT_EQ(surface_facts(open).boundary_edges, 3);
    EXPECT_THROW(require_closed_manifold(open, "test"), InputError);

    SurfaceMesh flipped = octahedron();
    std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
    EXPECT_EQ(surface_facts(flipped).misoriented_edges, 3);

    // Two octahedra sharing one vertex: every edge fine, one vertex pinched.
    SurfaceMesh a = octahedron(1.0), b = octahedron(1.0, {2, 0, 0});
    const auto offset = static_cast<int32_t>(a.points.size());
    for (Triangle t : b.triangles) {
        for (int32_t& v : t) v = (v == 1) ? 0 : v + offset; // b's vertex (1, 0, 0) is a's vertex 0
        a.triangles.push_back(t);
    }
    a.points.insert(a.points.end(), b.points.begin(), b.points.end());
    const SurfaceFacts f = surface_facts(a);
    EXPECT_EQ(f.boundary_edges, 0);
    EXPECT_EQ(f.nonmanifold_edges, 0);
    EXPECT_EQ(f.nonmanifold_vertices, 1);
    EXPECT_FALSE(f.closed_manifold());
    // Triangles join across edges, not at a pinched vertex.
    int32_t joined = 0;
    (void)triangle_components(a, &joined);
    EXPECT_EQ(joined, 2);
    EXPECT_EQ(f.components, 2);
}

// A closed manifold (the facts' one-pass route) and the same surface with a
// hole (the edge-by-edge route) must agree on what a hole cannot change.
TEST(SurfaceFacts, ClosedAndOpenRoutesAgreeOnComponentsAndEdges)
{
    SurfaceMesh two = octahedron(1.0);
    const SurfaceMesh b = octahedron(0.5, {5, 0, 0});
    const auto offset = static_cast<int32_t>(two.points.size());
    two.points.insert(two.points.end(), b.points.begin(), b.points.end());
    for (Triangle t : b.triangles) {
        for (int32_t& v : t) v += offset;
        two.triangles.push_back(t);
    }
    two.points.push_back({9, 9, 9}); // used by no triangle

    const SurfaceFacts closed = surface_facts(two);
    EXPECT_TRUE(closed.closed_manifold());
    EXPECT_EQ(closed.vertices, 12);
    EXPECT_EQ(closed.edges, static_cast<int64_t>(unique_edges(two).size()));
    EXPECT_EQ(closed.components, 2);
    EXPECT_EQ(closed.euler_characteristic, 4);
    EXPECT_NEAR(closed.signed_volume, 4.0 / 3.0 * (1.0 + 0.125), 1e-12);

    SurfaceMesh open = two;
    open.triangles.erase(open.triangles.begin()); // a hole in the first
    const SurfaceFacts holed = surface_facts(open);
    EXPECT_FALSE(holed.closed_manifold());
    EXPECT_EQ(holed.boundary_edges, 3);
    EXPECT_EQ(holed.edges, closed.edges);
    EXPECT_EQ(holed.components, closed.components);
    EXPECT_EQ(holed.vertices, closed.vertices);
}

// require_closed_manifold judges from the vertex links alone; it must
// refuse exactly the surfaces whose full facts are not a closed manifold,
// and count what is wrong in its message.
TEST(SurfaceFacts, RequireClosedManifoldRefusesExactlyWhatTheFactsRefuse)
{
    std::vector<std::pair<const char*, SurfaceMesh>> meshes;
    meshes.emplace_back("closed", octahedron());
    SurfaceMesh open = octahedron();
    open.triangles.pop_back();
    meshes.emplace_back("open", open);
    SurfaceMesh flipped = octahedron();
    std::swap(flipped.triangles[0][1], flipped.triangles[0][2]);
    meshes.emplace_back("flipped", flipped);
    SurfaceMesh doubled = octahedron();
    doubled.triangles.push_back(doubled.triangles[0]);
    meshes.emplace_back("a triangle twice", doubled);
    SurfaceMesh degenerate = octahedron();
    degenerate.triangles[0] = {0, 0, 4};
    meshes.emplace_back("degenerate", degenerate);
    SurfaceMesh pinched = octahedron(1.0), b = octahedron(1.0, {2, 0, 0});
    const auto offset = static_cast<int32_t>(pinched.points.size());
    for (Triangle t : b.triangles) {
        for (int32_t& v : t) v = (v == 1) ? 0 : v + offset;
        pinched.triangles.push_back(t);
    }
    pinched.points.insert(pinched.points.end(), b.points.begin(), b.points.end());
    meshes.emplace_back("pinched", pinched);

    for (const auto& [what, mesh] : meshes) {
        const SurfaceFacts facts = surface_facts(mesh);
        std::string message;
        try {
            require_closed_manifold(mesh, vertex_triangles(mesh), "test");
        } catch (const InputError& e) {
            message = e.what();
        }
        EXPECT_EQ(message.empty(), facts.closed_manifold()) << what << ": " << message;
        if (!facts.closed_manifold()) {
            EXPECT_NE(message.find(std::to_string(facts.nonmanifold_vertices) + " non-manifold vertices"),
                      std::string::npos)
                << what << ": " << message;
        }
    }
    EXPECT_EQ(surface_facts(pinched).nonmanifold_vertices, 1);
}

TEST(SurfaceFacts, OrientOutwardFlipsOnlyInwardSurfaces)
{
    SurfaceMesh m = octahedron();
    EXPECT_FALSE(orient_outward(m));
    for (Triangle& t : m.triangles) std::swap(t[0], t[1]);
    EXPECT_LT(signed_volume(m), 0);
    EXPECT_TRUE(orient_outward(m));
    EXPECT_GT(signed_volume(m), 0);
    EXPECT_TRUE(surface_facts(m).closed_manifold());
}

TEST(Adjacency, NeighboursAndFansOfTheOctahedron)
{
    const SurfaceMesh m = octahedron();
    const VertexTable n = vertex_neighbours(m);
    const VertexTable f = vertex_triangles(m);
    for (int32_t v = 0; v < 6; ++v) {
        EXPECT_EQ(n.size(v), 4);
        EXPECT_EQ(f.size(v), 4);
        EXPECT_TRUE(std::is_sorted(n.begin(v), n.end(v)));
        // The opposite vertex (v ^ 1) is the one not joined to v.
        EXPECT_EQ(std::find(n.begin(v), n.end(v), v ^ 1), n.end(v));
    }
    EXPECT_EQ(unique_edges(m).size(), 12u);
}

} // namespace
} // namespace scalemesh
