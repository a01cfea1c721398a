// read_surface on PLY, OBJ, VTP, MSH and STL: known shapes written by hand in
// each format, the real vmtk aorta surface, malformed variants, and
// deterministic random corruptions that must give an error, never a crash.

#include "core/errors.h"
#include "importers/stl_importer.h"
#include "importers/surface_importer.h"
#include "support/temp_dir.h"
#include "surface_files.h"

#include <gtest/gtest.h>

#include <random>

namespace scalemesh {
namespace {

using namespace scalemesh::test;

const std::filesystem::path kAorta = "../shared/data/vmtk_aorta_capped.stl";

struct Variant {
    std::string name; // file name, extension included
    std::string (*text)(const PolyMesh&);
};

const std::vector<Variant>& variants()
{
    static const std::vector<Variant> all = {
        {"ascii.ply", [](const PolyMesh& m) { return ply_text(m, PlyFormat::Ascii); }},
        {"little.ply", [](const PolyMesh& m) { return ply_text(m, PlyFormat::BinaryLittle); }},
        {"big.ply", [](const PolyMesh& m) { return ply_text(m, PlyFormat::BinaryBig); }},
        {"shape.obj", [](const PolyMesh& m) { return obj_text(m); }},
        {"ascii.vtp", [](const PolyMesh& m) { return vtp_text(m, VtpFormat::Ascii); }},
        {"binary32.vtp", [](const PolyMesh& m) { return vtp_text(m, VtpFormat::Binary32); }},
        {"binary64.vtp", [](const PolyMesh& m) { return vtp_text(m, VtpFormat::Binary64Separate); }},
        {"shape.msh", [](const PolyMesh& m) { return msh_text(m); }},
    };
    return all;
}

void expect_box(const SurfaceMesh& mesh, const Vec3& lo, const Vec3& hi, double tol, const std::string& what)
{
    Vec3 a, b;
    bounding_box(mesh, a, b);
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(a[k], lo[k], tol) << what << " axis " << k;
        EXPECT_NEAR(b[k], hi[k], tol) << what << " axis " << k;
    }
}

// The facts every successful read guarantees.
void expect_well_formed(const SurfaceMesh& mesh, const std::string& what)
{
    std::vector<char> used(mesh.points.size(), 0);
    for (const Triangle& t : mesh.triangles) {
        for (int32_t v : t) {
            ASSERT_GE(v, 0) << what;
            ASSERT_LT(v, static_cast<int32_t>(mesh.points.size())) << what;
            used[v] = 1;
        }
        EXPECT_TRUE(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) << what;
    }
    EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0) << what << ": every point is used";
    for (const Vec3& p : mesh.points) EXPECT_TRUE(std::isfinite(p.x + p.y + p.z)) << what;
}

TEST(SurfaceImporter, ReadsTheQuadCubeInEveryFormat)
{
    const TempDir tmp;
    for (const Variant& v : variants()) {
        const auto path = tmp.path / v.name;
        write_text(path, v.text(quad_cube()));
        const SurfaceMesh mesh = read_surface(path);
        const SurfaceFacts facts = surface_facts(mesh);
        EXPECT_EQ(facts.triangles, 12) << v.name << ": six quads fanned into two triangles each";
        EXPECT_EQ(facts.vertices, 8) << v.name;
        EXPECT_TRUE(facts.closed_manifold()) << v.name;
        EXPECT_NEAR(facts.signed_volume, 8.0, 1e-12) << v.name << ": the file's winding is kept (outward)";
        expect_box(mesh, {-1, -1, -1}, {1, 1, 1}, 0, v.name);
        expect_well_formed(mesh, v.name);
    }
}

TEST(SurfaceImporter, ReadsAnIcosphereInEveryFormatAsSTLDoes)
{
    const TempDir tmp;
    const PolyMesh sphere = icosphere(2, 5.0);
    for (const Variant& v : variants()) {
        const auto path = tmp.path / v.name;
        write_text(path, v.text(sphere));
        const SurfaceMesh mesh = read_surface(path);
        const SurfaceFacts facts = surface_facts(mesh);
        EXPECT_EQ(facts.triangles, 320) << v.name;
        EXPECT_EQ(facts.vertices, 162) << v.name;
        EXPECT_EQ(facts.euler_characteristic, 2) << v.name;
        EXPECT_TRUE(facts.closed_manifold()) << v.name;
        expect_box(mesh, {-5, -5, -5}, {5, 5, 5}, 1e-9, v.name);
        // Points in first-use order, as read_stl numbers them.
        EXPECT_EQ(mesh.triangles.front(), (Triangle{0, 1, 2})) << v.name;
    }
}

TEST(SurfaceImporter, ScalesToMillimetresByTheUnit)
{
    EXPECT_EQ(unit_to_mm("mm"), 1.0);
    EXPECT_EQ(unit_to_mm("cm"), 10.0);
    EXPECT_EQ(unit_to_mm("m"), 1000.0);
    EXPECT_EQ(unit_to_mm("um"), 1e-3);
    EXPECT_THROW(unit_to_mm("inch"), InputError);
    const TempDir tmp;
    for (const Variant& v : variants()) {
        const auto path = tmp.path / v.name;
        write_text(path, v.text(quad_cube()));
        expect_box(read_surface(path, unit_to_mm("m")), {-1000, -1000, -1000}, {1000, 1000, 1000}, 0, v.name);
        EXPECT_THROW(read_surface(path, 0.0), InputError) << v.name;
        EXPECT_THROW(read_surface(path, std::nan("")), InputError) << v.name;
    }
}

TEST(SurfaceImporter, DispatchesOnTheExtensionInAnyCase)
{
    const TempDir tmp;
    write_text(tmp.path / "CUBE.PLY", ply_text(quad_cube(), PlyFormat::Ascii));
    EXPECT_EQ(read_surface(tmp.path / "CUBE.PLY").triangles.size(), 12u);
    EXPECT_TRUE(is_surface_file("a/b.Vtp"));
    EXPECT_FALSE(is_surface_file("a/b.nii.gz"));
    write_text(tmp.path / "cube.off", "OFF\n");
    EXPECT_THROW(read_surface(tmp.path / "cube.off"), InputError);
    EXPECT_THROW(read_surface(tmp.path / "missing.ply"), IoError);
    std::filesystem::create_directory(tmp.path / "folder.ply");
    EXPECT_THROW(read_surface(tmp.path / "folder.ply"), IoError);
}

// The real vmtk aorta (binary STL, 12,932 triangles, closed, genus 0) through
// read_surface, then converted to every other format and read back.
TEST(SurfaceImporter, ReadsTheRealAortaInEveryFormat)
{
    ASSERT_TRUE(std::filesystem::exists(kAorta)) << "the shared data is missing: " << kAorta;
    const SurfaceMesh stl = read_surface(kAorta);
    const SurfaceFacts facts = surface_facts(stl);
    EXPECT_EQ(facts.triangles, 12932);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.euler_characteristic, 2);
    EXPECT_EQ(stl.points, read_stl(kAorta).points) << "read_surface of an STL is read_stl";
    Vec3 lo, hi;
    bounding_box(stl, lo, hi);

    const TempDir tmp;
    for (const Variant& v : variants()) {
        const auto path = tmp.path / v.name;
        write_text(path, v.text(from_surface(stl)));
        const SurfaceMesh mesh = read_surface(path);
        EXPECT_EQ(mesh.triangles, stl.triangles) << v.name;
        expect_box(mesh, lo, hi, 1e-12, v.name);
        EXPECT_NEAR(signed_volume(mesh), facts.signed_volume, 1e-9 * std::abs(facts.signed_volume)) << v.name;
    }
}

void expect_input_error(const std::filesystem::path& path, const std::string& text, const std::string& mentions)
{
    write_text(path, text);
    try {
        read_surface(path);
        ADD_FAILURE() << path.filename() << " was read: " << text.substr(0, 200);
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(mentions), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << "names the file: " << e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << path.filename() << ": " << typeid(e).name() << " " << e.what();
    }
}

std::string replace_first(std::string s, const std::string& from, const std::string& to)
{
    const size_t at = s.find(from);
    if (at == std::string::npos) throw std::logic_error("'" + from + "' is not in the text");
    return s.replace(at, from.size(), to);
}

PolyMesh with_nan(PolyMesh m)
{
    m.points[3].y = std::nan("");
    return m;
}

PolyMesh with_index(PolyMesh m, int32_t index)
{
    m.faces[2][1] = index;
    return m;
}

TEST(SurfaceImporter, RefusesMalformedPly)
{
    const TempDir tmp;
    const auto p = tmp.path / "bad.ply";
    for (PlyFormat f : {PlyFormat::Ascii, PlyFormat::BinaryLittle, PlyFormat::BinaryBig}) {
        const std::string good = ply_text(quad_cube(), f);
        expect_input_error(p, good.substr(0, good.size() - 30), "");                      // truncated
        expect_input_error(p, replace_first(good, "ply\n", "plx\n"), "does not begin");  // wrong magic
        expect_input_error(p, replace_first(good, "element face 6", "element face 0"), ""); // zero faces
        expect_input_error(p, replace_first(good, "element vertex 8", "element vertex 0"), "");
        expect_input_error(p, replace_first(good, "element vertex 8", "element vertex 4000000000"), "");
        expect_input_error(p, ply_text(with_nan(quad_cube()), f), "NaN");
        expect_input_error(p, ply_text(with_index(quad_cube(), 8), f), "refers to point 8");
        expect_input_error(p, ply_text(with_index(quad_cube(), -1), f), "refers to point -1");
        expect_input_error(p, replace_first(good, "end_header\n", ""), "header");
        expect_input_error(p, replace_first(good, "property double x\n", ""), "x, y and z");
    }
    // A list length far beyond the file, in binary: checked before any allocation.
    std::string huge = ply_text(quad_cube(), PlyFormat::BinaryLittle);
    huge = replace_first(huge, "property list uchar int", "property list uint int");
    expect_input_error(p, huge, "");
    expect_input_error(p, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                          "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                          "0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "2 corners");
}

TEST(SurfaceImporter, RefusesMalformedObj)
{
    const TempDir tmp;
    const auto p = tmp.path / "bad.obj";
    const std::string good = obj_text(quad_cube());
    expect_input_error(p, good.substr(0, good.find("\nf ")), "no faces");              // truncated before the faces
    expect_input_error(p, "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces");                // zero faces
    expect_input_error(p, "# nothing\n", "no faces");
    expect_input_error(p, obj_text(with_nan(quad_cube())), "not a finite number");
    expect_input_error(p, obj_text(with_index(quad_cube(), 8)), "refers to point 8");
    expect_input_error(p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -7\n", "refers to point");
    expect_input_error(p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "no faces");
    expect_input_error(p, "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n", "line 2");
    expect_input_error(p, "v 0 0 0\nv 1 0 0\nv 0 1 inf\nf 1 2 3\n", "line 3");
    expect_input_error(p, "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", "line 2");
    expect_input_error(p, std::string("\x89PNG\r\n\x1a\n", 8) + std::string(100, '\0'), "");
}

TEST(SurfaceImporter, RefusesMalformedVtp)
{
    const TempDir tmp;
    const auto p = tmp.path / "bad.vtp";
    for (VtpFormat f : {VtpFormat::Ascii, VtpFormat::Binary32, VtpFormat::Binary64Separate}) {
        const std::string good = vtp_text(quad_cube(), f);
        expect_input_error(p, good.substr(0, good.size() / 2), "not well-formed");     // truncated
        expect_input_error(p, replace_first(good, "<VTKFile", "<VTKFoo"), "");           // wrong root
        expect_input_error(p, replace_first(good, "PolyData\" version", "UnstructuredGrid\" version"), "not VTK PolyData");
        expect_input_error(p, replace_first(good, "NumberOfPolys=\"6\"", "NumberOfPolys=\"0\""), "");
        expect_input_error(p, replace_first(good, "NumberOfPoints=\"8\"", "NumberOfPoints=\"0\""), "");
        expect_input_error(p, replace_first(good, "NumberOfStrips=\"0\"", "NumberOfStrips=\"2\""), "Strips");
        expect_input_error(p, vtp_text(with_nan(quad_cube()), f), "NaN");
        expect_input_error(p, vtp_text(with_index(quad_cube(), 8), f), "");
    }
    const std::string good = vtp_text(quad_cube(), VtpFormat::Binary32);
    // Uncompressed data announced as compressed: the byte count is taken for a block count.
    expect_input_error(p, replace_first(good, "header_type=\"UInt32\"", "header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\""),
                       "compressed blocks");
    // Appended points whose data end within their header (more in test_vtk_xml.cpp).
    expect_input_error(p, replace_first(replace_first(good, "Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\"",
                                                      "Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\""),
                                        "</PolyData>", "</PolyData>\n  <AppendedData encoding=\"base64\">_AAAA</AppendedData>"),
                       "beyond the end of the file");
    const std::string points = "Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\">\n          ";
    expect_input_error(p, replace_first(good, points, points + "!"), "not base64");
}

TEST(SurfaceImporter, RefusesMalformedMsh)
{
    const TempDir tmp;
    const auto p = tmp.path / "bad.msh";
    const std::string good = msh_text(quad_cube());
    expect_input_error(p, replace_first(good, "$MeshFormat", "$MeshFormax"), "MeshFormat");
    expect_input_error(p, replace_first(good, "$Elements\n12\n", "$Elements\n0\n").substr(0, good.find("$Elements") + 12) +
                              "$EndElements\n",
                       "no triangles");
    expect_input_error(p, msh_text(with_index(quad_cube(), 99)), "node 100, which the $Nodes section does not define");
    expect_input_error(p, good.substr(0, good.size() / 2), "");
    expect_input_error(p, replace_first(good, "1 -1 -1 -1", "1 -1 nan -1"), "");
}

// The icosphere as MSH 4.1 ASCII, as Gmsh writes it: one surface entity, its
// nodes in one block and its triangles in another.
std::string msh41_text(const PolyMesh& m)
{
    std::ostringstream o;
    o.precision(17);
    const size_t n = m.points.size(), t = m.faces.size();
    o << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 1 0\n1 -1 -1 -1 1 1 1 0 0\n$EndEntities\n";
    o << "$Nodes\n1 " << n << " 1 " << n << "\n2 1 0 " << n << '\n';
    for (size_t i = 0; i < n; ++i) o << i + 1 << '\n';
    for (const Vec3& p : m.points) o << p.x << ' ' << p.y << ' ' << p.z << '\n';
    o << "$EndNodes\n$Elements\n1 " << t << " 1 " << t << "\n2 1 2 " << t << '\n';
    for (size_t f = 0; f < t; ++f)
        o << f + 1 << ' ' << m.faces[f][0] + 1 << ' ' << m.faces[f][1] + 1 << ' ' << m.faces[f][2] + 1 << '\n';
    o << "$EndElements\n";
    return o.str();
}

// The same mesh as binary MSH 2.2: counts on text lines, then records of
// little-endian ints and doubles.
std::string msh22_binary(const PolyMesh& m)
{
    std::string o = "$MeshFormat\n2.2 1 8\n";
    put(o, int32_t{1}, false);
    o += "\n$EndMeshFormat\n$Nodes\n" + std::to_string(m.points.size()) + "\n";
    for (size_t i = 0; i < m.points.size(); ++i) {
        put(o, static_cast<int32_t>(i + 1), false);
        for (const double x : {m.points[i].x, m.points[i].y, m.points[i].z}) put(o, x, false);
    }
    o += "\n$EndNodes\n$Elements\n" + std::to_string(m.faces.size()) + "\n";
    for (const int32_t v : {2, static_cast<int32_t>(m.faces.size()), 2}) put(o, v, false); // type, count, tags
    for (size_t f = 0; f < m.faces.size(); ++f)
        for (const int32_t v : {static_cast<int32_t>(f + 1), 0, 1, m.faces[f][0] + 1, m.faces[f][1] + 1,
                                m.faces[f][2] + 1})
            put(o, v, false);
    return o + "\n$EndElements\n";
}

// `msh41` with the line of its first element replaced by `line`.
std::string with_first_element(const std::string& msh41, const std::string& line)
{
    const size_t start = msh41.find('\n', msh41.find("$Elements\n") + 10);
    const size_t first = msh41.find('\n', start + 1) + 1;
    return msh41.substr(0, first) + line + msh41.substr(msh41.find('\n', first));
}

// Gmsh 4.8 trusts what an MSH file says: a node tag beyond int in an MSH4
// element made it segfault (found by fuzzing, fuzz/regressions/msh), and
// counts size its arrays before anything is read. read_surface checks the
// file first.
TEST(SurfaceImporter, RefusesMshThatGmshWouldMisread)
{
    const TempDir tmp;
    const auto p = tmp.path / "bad.msh";
    const PolyMesh sphere = icosphere(1);
    const std::string good41 = msh41_text(sphere);
    const std::string good22 = msh22_binary(sphere);
    for (const auto& [name, good] : {std::pair{"4.1 ASCII", good41}, std::pair{"2.2 binary", good22}}) {
        write_text(p, good);
        EXPECT_EQ(read_surface(p).triangles.size(), sphere.faces.size()) << name << " is read";
    }

    // The fuzzing find: an element's node tag of 234222412109 (an int of
    // 2^31 or more reads out of bounds in GModel::getMeshVertexByTag).
    expect_input_error(p, with_first_element(good41, "1 1 234222412109 3"), "'234222412109'");
    // A tag within int that no node has, a zero and a negative tag.
    expect_input_error(p, with_first_element(good41, "1 1 2 77"),
                       "element 1 refers to node 77, which the $Nodes section does not define");
    expect_input_error(p, with_first_element(good41, "1 1 0 3"), "node tag of element 1 '0'");
    expect_input_error(p, with_first_element(good41, "1 1 -2 3"), "node tag of element 1 '-2'");
    // The same in MSH 2.2 text: an undefined node, and a node defined twice.
    const std::string good22_text = msh_text(sphere);
    expect_input_error(p, msh_text(with_index(sphere, 3999)), "refers to node 4000");
    expect_input_error(p, replace_first(good22_text, "\n2 ", "\n1 "), "node 1 is defined twice");
    // ... and in binary: the first element's first node tag set to 4000.
    std::string bad22 = good22;
    const size_t first_element = bad22.find("$Elements\n") + 10 + std::to_string(sphere.faces.size()).size() + 1 + 12;
    const int32_t undefined = 4000;
    std::memcpy(bad22.data() + first_element + 12, &undefined, 4);
    expect_input_error(p, bad22, "refers to node 4000");

    // Counts larger than the file, which Gmsh would allocate for first.
    const std::string nodes_header = "$Nodes\n1 " + std::to_string(sphere.points.size());
    expect_input_error(p, replace_first(good41, nodes_header, "$Nodes\n1 2000000000"),
                       "it promises 2000000000 nodes");
    expect_input_error(p, replace_first(good22_text, "$Nodes\n42\n", "$Nodes\n2000000000\n"),
                       "it promises 2000000000 nodes");
    // Block counts that disagree with the header (Gmsh writes past its array).
    expect_input_error(p, replace_first(good41, "2 1 0 42\n", "2 1 0 41\n"), "its blocks hold 41");
    // An element in an entity of another dimension, a section without end.
    expect_input_error(p, replace_first(good41, "\n2 1 2 80\n", "\n1 1 2 80\n"), "(2D) in a 1D entity");
    expect_input_error(p, replace_first(good41, "$EndNodes", "$EndNodez"), "where $EndNodes should be");
    // Physical names index an array of four by dimension.
    const std::string names = "$PhysicalNames\n1\n7 1 \"wall\"\n$EndPhysicalNames\n";
    expect_input_error(p, replace_first(good41, "$Entities", names + "$Entities"), "dimension of physical name 1 '7'");
}

TEST(SurfaceImporter, StlThroughReadSurfaceRefusesLikeReadStl)
{
    const TempDir tmp;
    const auto p = tmp.path / "bad.stl";
    expect_input_error(p, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 nan\nvertex 1 0 0\nvertex 0 1 0\n"
                          "endloop\nendfacet\nendsolid x\n", "NaN");
    expect_input_error(p, std::string(84, '\0'), "no triangles");
}

// Deterministic random corruptions of each format's valid file: every read
// either succeeds with a well-formed mesh or throws InputError or IoError.
// Under AddressSanitizer (the fast label) this also checks for memory errors.
TEST(SurfaceImporter, SurvivesRandomCorruptions)
{
    const TempDir tmp;
    std::vector<std::pair<std::string, std::string>> files;
    for (const Variant& v : variants()) files.push_back({v.name, v.text(icosphere(1))});
    {
        // A binary STL of the same sphere.
        std::string stl(80, ' ');
        const PolyMesh m = icosphere(1);
        put(stl, static_cast<uint32_t>(m.faces.size()), false);
        for (const auto& f : m.faces) {
            for (int k = 0; k < 3; ++k) put(stl, 0.0f, false);
            for (int32_t v : f)
                for (int k = 0; k < 3; ++k) put(stl, static_cast<float>(m.points[v][k]), false);
            stl += std::string(2, '\0');
        }
        files.push_back({"binary.stl", stl});
    }
    std::mt19937 random(20240611);
    for (const auto& [name, good] : files) {
        // Gmsh opens a session per read: fewer rounds keep the test fast.
        const int rounds = name.ends_with(".msh") ? 120 : 300;
        int errors = 0, reads = 0;
        for (int round = 0; round < rounds; ++round) {
            std::string bad = good;
            switch (round % 4) {
            case 0: // a few bytes overwritten
            case 1:
                for (int k = 0, n = 1 + static_cast<int>(random() % 4); k < n; ++k)
                    bad[random() % bad.size()] = static_cast<char>(random() % 256);
                break;
            case 2: // truncated
                bad.resize(random() % bad.size());
                break;
            case 3: { // a digit or byte changed into another plausible one
                const size_t at = random() % bad.size();
                bad[at] = "0123456789-.e \n9"[random() % 16];
                break;
            }
            }
            const auto path = tmp.path / ("fuzz-" + name);
            write_text(path, bad);
            try {
                const SurfaceMesh mesh = read_surface(path);
                expect_well_formed(mesh, name + " round " + std::to_string(round));
                ++reads;
            } catch (const InputError&) {
                ++errors;
            } catch (const IoError&) {
                ++errors;
            } catch (const std::exception& e) {
                ADD_FAILURE() << name << " round " << round << ": unexpected " << typeid(e).name() << ": " << e.what();
            }
        }
        EXPECT_GT(errors, 0) << name << ": some corruptions must be refused";
        EXPECT_EQ(errors + reads, rounds) << name;
    }
}

} // namespace
} // namespace scalemesh
