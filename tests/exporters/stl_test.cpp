#include "core/errors.h"
#include "exporters/surface_writers.h"
#include "importers/stl_importer.h"
#include "test_support.h"

#include <array>
#include <cstring>
#include <limits>

namespace scalemesh::test {
namespace {

using Facet = std::array<float, 9>; // three corners

// A binary STL made byte by byte, independent of write_surface.
std::string binary_stl(const std::vector<Facet>& facets, const std::string& header = "made by the test")
{
    std::string bytes(84 + 50 * facets.size(), '\0');
    std::memcpy(bytes.data(), header.data(), std::min<size_t>(header.size(), 80));
    const auto count = uint32_t(facets.size());
    std::memcpy(bytes.data() + 80, &count, 4);
    for (size_t f = 0; f < facets.size(); ++f) std::memcpy(bytes.data() + 84 + 50 * f + 12, facets[f].data(), 36);
    return bytes;
}

// Unit right tetrahedron, outward normals, volume 1/6.
std::vector<Facet> tetrahedron_facets()
{
    return {Facet{0, 0, 0, 0, 1, 0, 1, 0, 0}, Facet{0, 0, 0, 1, 0, 0, 0, 0, 1}, Facet{0, 0, 0, 0, 0, 1, 0, 1, 0},
            Facet{1, 0, 0, 0, 1, 0, 0, 0, 1}};
}

class Stl : public ScratchDir {
protected:
    void expect_round_trip(const SurfaceMesh& mesh)
    {
        const auto file = dir / "shape.stl";
        write_surface(mesh, {}, file);
        int64_t degenerate = -1;
        const SurfaceMesh back = read_stl(file, 1.0, &degenerate);

        EXPECT_EQ(degenerate, 0);
        ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
        EXPECT_EQ(back.points.size(), mesh.points.size()); // welding restores the shared vertices
        // Triangle order and corner order are kept, so corners compare one to one.
        double worst = 0;
        for (size_t f = 0; f < mesh.triangles.size(); ++f)
            for (int k = 0; k < 3; ++k) {
                const Vec3& p = mesh.points[mesh.triangles[f][k]];
                const Vec3& q = back.points[back.triangles[f][k]];
                for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(p[c] - q[c]) / std::max(1.0, std::abs(p[c])));
            }
        EXPECT_LE(worst, 1.0 / (1 << 23)); // float32 rounding: half an ulp is 2^-24 relative

        const SurfaceFacts before = surface_facts(mesh), after = surface_facts(back);
        EXPECT_TRUE(after.closed_manifold());
        EXPECT_EQ(after.euler_characteristic, before.euler_characteristic);
        EXPECT_GT(before.signed_volume, 0);
        EXPECT_GT(after.signed_volume, 0);
        EXPECT_NEAR(after.signed_volume / before.signed_volume, 1.0, 1e-5);
    }
};

TEST(StlShapes, TestShapesAreClosedAndOutward)
{
    for (const SurfaceMesh& mesh : {octahedron(1), icosphere(1, 2), uv_sphere(1, 16, 9)}) {
        const SurfaceFacts facts = surface_facts(mesh);
        EXPECT_TRUE(facts.closed_manifold());
        EXPECT_EQ(facts.euler_characteristic, 2);
        EXPECT_GT(facts.signed_volume, 0);
    }
    EXPECT_NEAR(signed_volume(octahedron(2)), 4.0 / 3.0 * 8, 1e-12);
}

TEST_F(Stl, OctahedronRoundTrip) { expect_round_trip(translated(octahedron(12.5), {100.25, -40.5, 7})); }

TEST_F(Stl, IcosphereRoundTrip) { expect_round_trip(translated(icosphere(12.5, 3), {100.25, -40.5, 7})); }

TEST_F(Stl, UvSphereRoundTrip) { expect_round_trip(translated(uv_sphere(3.3, 40, 21), {-0.1, 250, 1e3})); }

TEST_F(Stl, ScaleMultipliesCoordinates)
{
    write_surface(octahedron(1), {}, dir / "m.stl");
    const SurfaceMesh mm = read_stl(dir / "m.stl", 1000.0);
    EXPECT_NEAR(signed_volume(mm), 4.0 / 3.0 * 1e9, 1e-3);
    EXPECT_THROW(read_stl(dir / "m.stl", 0.0), InputError);
    EXPECT_THROW(read_stl(dir / "m.stl", std::numeric_limits<double>::quiet_NaN()), InputError);
}

TEST_F(Stl, WeldsSignedZerosAndRemovesDegenerateTriangles)
{
    std::vector<Facet> facets = tetrahedron_facets();
    facets[1][0] = -0.0f; // the same point as (0, 0, 0)
    facets.push_back({1, 0, 0, 1, 0, 0, 0, 0, 1}); // two equal corners
    facets.push_back({0, 0, 1, 0, 0, 1, 0, 0, 1}); // a point
    facets.push_back({5, 5, 5, 5, 5, 5, 6, 6, 6}); // degenerate, and its points are used nowhere else
    write_text(dir / "t.stl", binary_stl(facets));

    int64_t degenerate = -1;
    const SurfaceMesh mesh = read_stl(dir / "t.stl", 1.0, &degenerate);
    EXPECT_EQ(degenerate, 3);
    EXPECT_EQ(mesh.triangles.size(), 4u);
    EXPECT_EQ(mesh.points.size(), 4u); // no point left over from the dropped triangles
    const SurfaceFacts facts = surface_facts(mesh);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_NEAR(facts.signed_volume, 1.0 / 6.0, 1e-12);
}

TEST_F(Stl, AsciiTetrahedron)
{
    // Mixed spacing, a named solid, exponents, a '+' sign and CRLF line ends.
    write_text(dir / "a.stl", "solid my tetra\r\n"
                              "  facet normal 0 0 -1\r\n    outer loop\r\n"
                              "      vertex 0 0 0\r\n      vertex 0 1e0 0\r\n      vertex +1.0 0 0\r\n"
                              "    endloop\r\n  endfacet\r\n"
                              "facet normal 0 -1 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 0 1\nendloop\nendfacet\n"
                              "facet normal -1 0 0\nouter loop\nvertex 0 0 0\nvertex 0 0 1\nvertex 0 1 0\nendloop\nendfacet\n"
                              "endsolid my tetra\n"
                              "solid second\n"
                              "facet normal 1 1 1\n outer loop\n  vertex 1 0 0\n  vertex 0 1 0\n  vertex 0 0 1\n endloop\nendfacet\n"
                              "endsolid second\n");
    const SurfaceMesh mesh = read_stl(dir / "a.stl");
    EXPECT_EQ(mesh.triangles.size(), 4u);
    EXPECT_EQ(mesh.points.size(), 4u);
    const SurfaceFacts facts = surface_facts(mesh);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_NEAR(facts.signed_volume, 1.0 / 6.0, 1e-12);

    // The same triangles in binary give the same mesh.
    write_text(dir / "b.stl", binary_stl(tetrahedron_facets()));
    const SurfaceMesh binary = read_stl(dir / "b.stl");
    EXPECT_EQ(binary.points, mesh.points);
    EXPECT_EQ(binary.triangles, mesh.triangles);
}

TEST_F(Stl, BinaryHeaderStartingWithSolidIsBinary)
{
    // Some CAD programs begin binary headers with "solid"; the size decides.
    write_text(dir / "s.stl", binary_stl(tetrahedron_facets(), "solid part facet normal"));
    const SurfaceMesh mesh = read_stl(dir / "s.stl");
    EXPECT_EQ(mesh.triangles.size(), 4u);
    EXPECT_NEAR(signed_volume(mesh), 1.0 / 6.0, 1e-12);
}

TEST(StlAorta, RealCappedAortaIsClosedGenusZeroAndKeepsTheFilesWinding)
{
    const std::filesystem::path path = "../shared/data/vmtk_aorta_capped.stl";
    int64_t degenerate = -1;
    const SurfaceMesh mesh = read_stl(path, 1.0, &degenerate);
    EXPECT_EQ(degenerate, 0);
    ASSERT_EQ(mesh.triangles.size(), 12932u);
    const SurfaceFacts facts = surface_facts(mesh);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_NO_THROW(require_closed_manifold(mesh, "the vmtk aorta"));
    EXPECT_EQ(facts.components, 1);
    EXPECT_EQ(facts.euler_characteristic, 2);
    EXPECT_EQ(facts.vertices, static_cast<int64_t>(mesh.points.size()));

    // The file is wound inward: its triangles enclose a negative signed volume
    // and its stored facet normals agree with that winding. The reader keeps
    // the file's orientation (callers orient), so every stored normal must
    // point along the normal of the triangle read back.
    EXPECT_LT(facts.signed_volume, 0);
    EXPECT_NEAR(-facts.signed_volume, 13184.27, 0.01); // mm^3, computed from the raw file
    const std::string bytes = read_text(path);
    int64_t against = 0;
    for (size_t f = 0; f < mesh.triangles.size(); ++f) {
        float stored[3];
        std::memcpy(stored, bytes.data() + 84 + 50 * f, sizeof stored);
        const Triangle& t = mesh.triangles[f];
        const Vec3 n = cross(mesh.points[t[1]] - mesh.points[t[0]], mesh.points[t[2]] - mesh.points[t[0]]);
        if (dot(n, Vec3{stored[0], stored[1], stored[2]}) <= 0) ++against;
    }
    EXPECT_EQ(against, 0);
}

TEST_F(Stl, MissingFileOrDirectoryIsIoError)
{
    EXPECT_THROW(read_stl(dir / "absent.stl"), IoError);
    EXPECT_THROW(read_stl(dir), IoError);
}

TEST_F(Stl, DamagedBinaryFilesAreInputErrors)
{
    const std::string good = binary_stl(tetrahedron_facets());
    const auto expect_input_error = [&](const std::string& bytes, const std::string& words) {
        write_text(dir / "bad.stl", bytes);
        try {
            read_stl(dir / "bad.stl");
            ADD_FAILURE() << "no error for a file of " << bytes.size() << " bytes";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("Hint:"), std::string::npos) << e.what();
        }
    };
    expect_input_error("", "is empty");
    expect_input_error(good.substr(0, good.size() - 10), "truncated");      // cut in the last facet
    expect_input_error(good.substr(0, 84 + 50 * 2), "truncated");          // whole facets missing
    expect_input_error(good + std::string(7, '\0'), "truncated");          // size fits no count
    expect_input_error(good.substr(0, 40), "too short");                   // not even a header
    expect_input_error(binary_stl({}), "no triangles");
    expect_input_error("PK\x03\x04 this is a zip archive, not a surface", "not an STL");

    std::vector<Facet> facets = tetrahedron_facets();
    facets[2][4] = std::numeric_limits<float>::quiet_NaN();
    expect_input_error(binary_stl(facets), "facet 3 of 4");
    facets[2][4] = std::numeric_limits<float>::infinity();
    expect_input_error(binary_stl(facets), "NaN or infinite");

    std::vector<Facet> flat(3, Facet{1, 1, 1, 1, 1, 1, 2, 2, 2});
    expect_input_error(binary_stl(flat), "degenerate");
}

TEST_F(Stl, DamagedAsciiFilesAreInputErrors)
{
    const std::string facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
    const auto expect_input_error = [&](const std::string& text, const std::string& words) {
        write_text(dir / "bad.stl", text);
        try {
            read_stl(dir / "bad.stl");
            ADD_FAILURE() << "no error for:\n" << text;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
        }
    };
    expect_input_error("solid empty\nendsolid empty\n", "not an STL");  // no facet at all
    expect_input_error("solid s\n" + facet.substr(0, facet.find("endloop")), "truncated"); // ends inside a facet
    expect_input_error("solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\n",
                       "line 7");                                        // two vertices
    expect_input_error("solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
                       "vertex 1 1 0\nendloop\nendfacet\n",
                       "more than three vertices");
    expect_input_error("solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 nan\nvertex 1 0 0\nvertex 0 1 0\n"
                       "endloop\nendfacet\nendsolid\n",
                       "NaN or infinite");
    expect_input_error("solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 1,5\nvertex 1 0 0\nvertex 0 1 0\n"
                       "endloop\nendfacet\nendsolid\n",
                       "'1,5' is not");
    expect_input_error("solid s\n" + facet + "vertex 1 2 3\nendsolid s\n", "vertex outside a facet");
    expect_input_error("solid s\n" + facet + "polygon 3\nendsolid s\n", "unexpected 'polygon'");
}

} // namespace
} // namespace scalemesh::test
