#include "core/errors.h"
#include "exporters/surface_writers.h"
#include "gmsh_io/gmsh_session.h"
#include "gmsh_io/msh_reader.h"
#include "support/gmsh_host.h"
#include "test_support.h"

#include <gmsh.h>

#include <algorithm>
#include <numbers>

namespace scalemesh::test {
namespace {

struct MshFormat {
    double version;
    bool binary;
};

void PrintTo(const MshFormat& format, std::ostream* out)
{
    *out << "MSH " << format.version << (format.binary ? " binary" : " ASCII");
}

std::string format_name(const ::testing::TestParamInfo<MshFormat>& info)
{
    return std::string(info.param.version == 4.1 ? "v41" : "v22") + (info.param.binary ? "_binary" : "_ascii");
}

// For each point of `back`, the point of `original` at the same place: MSH 2.2
// renumbers nodes, so points are matched by coordinates (MSH ASCII keeps 16
// significant digits).
std::vector<int32_t> match_points(const SurfaceMesh& original, const SurfaceMesh& back)
{
    std::vector<int32_t> match(back.points.size(), -1);
    for (size_t i = 0; i < back.points.size(); ++i)
        for (size_t j = 0; j < original.points.size(); ++j)
            if (distance(back.points[i], original.points[j]) <= 1e-13 * (1 + norm(original.points[j]))) {
                match[i] = int32_t(j);
                break;
            }
    return match;
}

// The triangle rotated to start at its smallest index: same orientation.
Triangle canonical(Triangle t)
{
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    return t;
}

// Triangles of `back` in the numbering of `original`, with their patches, sorted.
std::vector<std::pair<Triangle, int32_t>> mapped_triangles(const SurfaceMesh& back, const std::vector<int32_t>& match)
{
    std::vector<std::pair<Triangle, int32_t>> result;
    for (size_t f = 0; f < back.triangles.size(); ++f) {
        const Triangle& t = back.triangles[f];
        result.push_back({canonical({match[t[0]], match[t[1]], match[t[2]]}),
                          back.triangle_patch.empty() ? 0 : back.triangle_patch[f]});
    }
    std::sort(result.begin(), result.end());
    return result;
}

std::vector<std::pair<Triangle, int32_t>> sorted_triangles(const SurfaceMesh& mesh)
{
    std::vector<std::int32_t> identity(mesh.points.size());
    for (size_t i = 0; i < identity.size(); ++i) identity[i] = int32_t(i);
    return mapped_triangles(mesh, identity);
}

size_t occurrences(const std::string& text, const std::string& word)
{
    size_t n = 0;
    for (size_t at = text.find(word); at != std::string::npos; at = text.find(word, at + 1)) ++n;
    return n;
}

std::vector<VertexField> sample_fields(const SurfaceMesh& mesh)
{
    VertexField d{"D", {}}, d_out{"d out", {}};
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        d.values.push_back(1 + mesh.points[i].x * mesh.points[i].x / 3);
        d_out.values.push_back(std::numbers::pi + 0.1 * double(i));
    }
    return {d, d_out};
}

class Msh : public ScratchDir, public ::testing::WithParamInterface<MshFormat> {
protected:
    SurfaceWriteOptions options() const
    {
        SurfaceWriteOptions o;
        o.msh_version = GetParam().version;
        o.msh_binary = GetParam().binary;
        return o;
    }
};

TEST_P(Msh, RoundTripKeepsNodesTrianglesWallGroupAndFields)
{
    const SurfaceMesh mesh = translated(icosphere(10, 3), {120.5, -33.25, 8});
    const std::vector<VertexField> fields = sample_fields(mesh);
    const auto file = dir / "surface.msh";

    ::testing::internal::CaptureStdout();
    ::testing::internal::CaptureStderr();
    write_surface(mesh, fields, file, options());
    const MshSurface back = read_msh_surface(file);
    EXPECT_EQ(::testing::internal::GetCapturedStdout(), "");
    EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");

    const std::string bytes = read_text(file);
    const std::string header = GetParam().version == 4.1 ? "4.1 " : "2.2 ";
    EXPECT_EQ(bytes.rfind("$MeshFormat\n" + header + (GetParam().binary ? "1" : "0"), 0), 0u) << bytes.substr(0, 30);
    EXPECT_EQ(occurrences(bytes, "$Nodes"), 1u);    // the views did not repeat the mesh
    EXPECT_EQ(occurrences(bytes, "$NodeData"), 2u); // one per field

    ASSERT_EQ(back.mesh.points.size(), mesh.points.size());
    const std::vector<int32_t> match = match_points(mesh, back.mesh);
    std::vector<int32_t> seen = match;
    std::sort(seen.begin(), seen.end());
    for (size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], int32_t(i)) << "points do not match one to one";
    EXPECT_EQ(mapped_triangles(back.mesh, match), sorted_triangles(mesh)); // same triangles, same orientation
    if (GetParam().version == 4.1) {
        // MSH 4.1 keeps node and element tags: same numbering and order.
        for (size_t i = 0; i < match.size(); ++i) EXPECT_EQ(match[i], int32_t(i));
        EXPECT_EQ(back.mesh.triangles, mesh.triangles);
    }
    EXPECT_EQ(back.patch_names, (std::map<int32_t, std::string>{{0, "wall"}}));
    EXPECT_GT(signed_volume(back.mesh), 0);

    ASSERT_EQ(back.fields.size(), fields.size());
    for (size_t k = 0; k < fields.size(); ++k) {
        EXPECT_EQ(back.fields[k].name, fields[k].name);
        ASSERT_EQ(back.fields[k].values.size(), mesh.points.size());
        for (size_t i = 0; i < match.size(); ++i)
            EXPECT_NEAR(back.fields[k].values[i], fields[k].values[match[i]], 1e-14 * std::abs(fields[k].values[match[i]]))
                << fields[k].name << " at point " << i;
    }
}

TEST_P(Msh, PatchesBecomeNamedPhysicalGroups)
{
    SurfaceMesh mesh = icosphere(5, 2);
    for (const Triangle& t : mesh.triangles) {
        const Vec3 centre = (mesh.points[t[0]] + mesh.points[t[1]] + mesh.points[t[2]]) / 3.0;
        mesh.triangle_patch.push_back(centre.z > 2 ? 3 : (centre.x > 2 ? 7 : 0));
    }
    SurfaceWriteOptions o = options();
    o.patch_names = {{3, "outlet"}, {12, "unused"}};
    write_surface(mesh, {}, dir / "patches.msh", o);
    const MshSurface back = read_msh_surface(dir / "patches.msh");

    EXPECT_EQ(back.patch_names, (std::map<int32_t, std::string>{{0, "wall"}, {3, "outlet"}, {7, "patch_7"}}));
    ASSERT_EQ(back.mesh.points.size(), mesh.points.size());
    EXPECT_EQ(mapped_triangles(back.mesh, match_points(mesh, back.mesh)), sorted_triangles(mesh));
    EXPECT_TRUE(surface_facts(back.mesh).closed_manifold());
}

TEST_P(Msh, PointsUsedByNoTriangleAreLeftOut)
{
    SurfaceMesh mesh = octahedron(2);
    mesh.points.insert(mesh.points.begin() + 2, Vec3{9, 9, 9});
    for (Triangle& t : mesh.triangles)
        for (int32_t& v : t)
            if (v >= 2) ++v;
    const VertexField field{"D", {1, 2, 99, 3, 4, 5, 6}};
    write_surface(mesh, {field}, dir / "unused.msh", options());
    const MshSurface back = read_msh_surface(dir / "unused.msh");

    ASSERT_EQ(back.mesh.points.size(), 6u);
    const std::vector<int32_t> match = match_points(mesh, back.mesh);
    ASSERT_EQ(back.fields.size(), 1u);
    for (size_t i = 0; i < match.size(); ++i) {
        ASSERT_NE(match[i], 2);
        EXPECT_EQ(back.fields[0].values[i], field.values[match[i]]);
    }
    EXPECT_EQ(mapped_triangles(back.mesh, match), sorted_triangles(mesh));
}

INSTANTIATE_TEST_SUITE_P(Formats, Msh,
                         ::testing::Values(MshFormat{4.1, false}, MshFormat{4.1, true}, MshFormat{2.2, false},
                                           MshFormat{2.2, true}),
                         format_name);

class MshSession : public ScratchDir {};

TEST_F(MshSession, WritingInsideACallersSessionLeavesItsModelAndOptions)
{
    GmshSession session;
    gmsh::model::add("caller");
    gmsh::option::setNumber("Mesh.MshFileVersion", 2.2);

    write_surface(octahedron(1), {VertexField{"D", std::vector<double>(6, 1.0)}}, dir / "inner.msh");
    const MshSurface back = read_msh_surface(dir / "inner.msh");
    EXPECT_EQ(back.fields.size(), 1u);

    EXPECT_TRUE(host_model_current_and_listed_once("caller"));
    std::vector<std::string> models;
    gmsh::model::list(models);
    for (const std::string& name : models) EXPECT_EQ(name.rfind("scalemesh_", 0), std::string::npos) << name;
    std::vector<int> views;
    gmsh::view::getTags(views);
    EXPECT_TRUE(views.empty());
    double version = 0, terminal = 1;
    gmsh::option::getNumber("Mesh.MshFileVersion", version);
    gmsh::option::getNumber("General.Terminal", terminal);
    EXPECT_EQ(version, 2.2);
    EXPECT_EQ(terminal, 0);
    // The inner write used 4.1, not the caller's setting.
    EXPECT_EQ(read_text(dir / "inner.msh").rfind("$MeshFormat\n4.1", 0), 0u);
}

TEST_F(MshSession, SessionsCanFollowEachOther)
{
    for (int i = 0; i < 3; ++i) {
        write_surface(octahedron(1 + i), {}, dir / "again.msh");
        EXPECT_NEAR(signed_volume(read_msh_surface(dir / "again.msh").mesh), 4.0 / 3.0 * std::pow(1 + i, 3), 1e-12);
    }
}

TEST_F(MshSession, BadVersionAndDamagedFilesAreReported)
{
    SurfaceWriteOptions o;
    o.msh_version = 3.0;
    EXPECT_THROW(write_surface(octahedron(1), {}, dir / "v3.msh", o), InputError);
    EXPECT_TRUE(entries().empty());

    EXPECT_THROW(read_msh_surface(dir / "absent.msh"), IoError);
    write_text(dir / "damaged.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 3 1 3\n2 1 0 3\n1\n");
    EXPECT_THROW(read_msh_surface(dir / "damaged.msh"), IoError);
    // Without an MSH header Gmsh would run the file as a .geo script.
    write_text(dir / "script.msh", "Point(1) = {0, 0, 0};\n");
    EXPECT_THROW(read_msh_surface(dir / "script.msh"), InputError);
    EXPECT_THROW(read_msh_surface("../shared/data/vmtk_aorta_capped.stl"), InputError);
}

} // namespace
} // namespace scalemesh::test
