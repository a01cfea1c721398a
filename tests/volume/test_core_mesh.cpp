// mesh_core (core_mesh.h): Gmsh fills a closed boundary with tets through the
// boundary's own points and the given inside points, alone or inside a
// host's Gmsh session, which it leaves as it found it.

#include "volume/core_mesh.h"

#include "core/tet_mesh.h"
#include "gmsh_io/gmsh_session.h"
#include "support/gmsh_host.h"

#include <gmsh.h>
#include <gtest/gtest.h>

#include <utility>
#include <vector>

namespace scalemesh {
namespace {

// The box [lo, hi]^3 as 12 triangles, outward wound (inward with `cavity`),
// its corners appended to `mesh`.
void add_box(SurfaceMesh& mesh, double lo, double hi, bool cavity = false)
{
    const int32_t base = static_cast<int32_t>(mesh.points.size());
    for (int k = 0; k < 8; ++k) mesh.points.push_back({k & 1 ? hi : lo, k & 2 ? hi : lo, k & 4 ? hi : lo});
    const int32_t faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : faces) {
        Triangle a{base + q[0], base + q[1], base + q[2]}, b{base + q[0], base + q[2], base + q[3]};
        if (cavity) std::swap(a[1], a[2]), std::swap(b[1], b[2]);
        mesh.triangles.push_back(a);
        mesh.triangles.push_back(b);
    }
}

double total_volume(const TetMesh& mesh)
{
    double v = 0;
    for (const Tet& t : mesh.tets)
        v += tet_volume6(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]) / 6;
    return v;
}

// The facts mesh_core promises: the boundary's points first and unchanged,
// the boundary its faces, every tet positive, every boundary triangle the
// face of one tet.
void expect_core_facts(const SurfaceMesh& boundary, const TetMesh& mesh)
{
    ASSERT_GE(mesh.points.size(), boundary.points.size());
    for (size_t i = 0; i < boundary.points.size(); ++i) EXPECT_EQ(mesh.points[i], boundary.points[i]);
    EXPECT_EQ(mesh.boundary_faces, boundary.triangles);
    const TetMeshFacts facts = tet_mesh_facts(mesh);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_TRUE(facts.boundary_matches);
}

TEST(CoreMesh, FillsABoxThroughItsPoints)
{
    SurfaceMesh box;
    add_box(box, 0, 2);
    const std::vector<Vec3> inside = {{1, 1, 1}, {0.5, 0.6, 0.7}, {1.5, 1.4, 1.3}};
    const TetMesh mesh = mesh_core(box, inside);
    expect_core_facts(box, mesh);
    EXPECT_NEAR(total_volume(mesh), 8.0, 1e-9);
    EXPECT_EQ(mesh.points.size(), box.points.size() + inside.size()) << "Gmsh adds no point of its own";
}

TEST(CoreMesh, LeavesACavityEmpty)
{
    SurfaceMesh shell;
    add_box(shell, 0, 3);
    add_box(shell, 1, 2, /*cavity=*/true);
    const TetMesh mesh = mesh_core(shell, {{0.5, 0.5, 0.5}, {2.5, 2.5, 2.5}});
    expect_core_facts(shell, mesh);
    EXPECT_NEAR(total_volume(mesh), 27.0 - 1.0, 1e-9);
}

// Inside a host's session (adopted, as mesh_gmsh_model does), the core is
// meshed on a model of its own: the host's model is current again after,
// the session still open, the host's options as they were.
TEST(CoreMesh, InAHostSessionLeavesTheHostsModelAndOptions)
{
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::model::add("host");
    gmsh::option::setNumber("Mesh.Algorithm3D", 4);
    {
        const GmshSession host(GmshSession::Host{});
        SurfaceMesh box;
        add_box(box, 0, 1);
        const TetMesh mesh = mesh_core(box, {{0.5, 0.5, 0.5}});
        expect_core_facts(box, mesh);
    }
    EXPECT_TRUE(host_model_current_and_listed_once("host"));
    double algorithm = 0;
    gmsh::option::getNumber("Mesh.Algorithm3D", algorithm);
    EXPECT_EQ(algorithm, 4);
    gmsh::finalize();
    // A session of its own again afterwards.
    SurfaceMesh box;
    add_box(box, 0, 1);
    expect_core_facts(box, mesh_core(box, {}));
}

} // namespace
} // namespace scalemesh
