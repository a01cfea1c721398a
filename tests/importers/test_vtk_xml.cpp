// VTK XML files as VMTK, SimVascular and ParaView write them: .vtp surfaces
// and their face labels, and .vti images, in every encoding (ascii, inline
// binary, appended raw and base64; plain or zlib; UInt32 or UInt64 headers;
// little- and big-endian), written by tests/importers/vtk_xml_writer.h and
// read back to the bit; a .vti label image read like the same mask as NIfTI;
// damaged and hostile files refused with InputError, never a crash.

#include "core/errors.h"
#include "core/surface_mesh.h"
#include "importers/image_importer.h"
#include "importers/surface_importer.h"
#include "isosurface/marching_cubes.h"
#include "support/temp_dir.h"
#include "vtk_xml_writer.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <set>

namespace scalemesh {
namespace {

namespace fs = std::filesystem;
using test::PolyMesh;
using test::vtk::Encoding;
using test::vtk::Options;

// An icosphere whose points are moved off any round value, and a label per
// face.
PolyMesh bumpy_sphere()
{
    PolyMesh m = test::icosphere(2, 3.0);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> jitter(-0.05, 0.05);
    for (Vec3& p : m.points) p = p + Vec3{jitter(rng), jitter(rng), jitter(rng)} + Vec3{10.125, -4.5, 1e3};
    return m;
}

std::vector<int32_t> face_labels(size_t n)
{
    std::vector<int32_t> labels(n);
    for (size_t i = 0; i < n; ++i) labels[i] = static_cast<int32_t>(i % 7) + (i % 3 == 0 ? -100000 : 1);
    return labels;
}

bool same_bits(double a, double b) { return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b); }

// Triangle k of the result is face k of `m` (nothing is dropped), with the
// same corner coordinates to the bit, in the same order; every point used.
void expect_same_surface(const SurfaceMesh& got, const PolyMesh& m, bool float32, const std::string& what)
{
    ASSERT_EQ(got.triangles.size(), m.faces.size()) << what;
    EXPECT_EQ(got.points.size(), m.points.size()) << what;
    const auto stored = [float32](double v) { return float32 ? static_cast<double>(static_cast<float>(v)) : v; };
    for (size_t k = 0; k < m.faces.size(); ++k)
        for (int c = 0; c < 3; ++c) {
            const Vec3& p = got.points[got.triangles[k][c]];
            const Vec3& q = m.points[m.faces[k][c]];
            for (int d = 0; d < 3; ++d)
                ASSERT_TRUE(same_bits(p[d], stored(q[d]))) << what << " triangle " << k << " corner " << c;
        }
}

void write(const fs::path& path, const std::string& bytes) { test::write_text(path, bytes); }

// Reads `bytes` as `name` in `dir` and expects an InputError whose message
// holds `expected`.
template <typename Read>
void expect_input_error(const TempDir& dir, const std::string& name, const std::string& bytes,
                        const std::string& expected, const Read& read)
{
    const fs::path path = dir.path / name;
    write(path, bytes);
    try {
        read(path);
        ADD_FAILURE() << name << ": read without error, expected '" << expected << "'";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
            << name << ": '" << e.what() << "' does not say '" << expected << "'";
    } catch (const std::exception& e) {
        ADD_FAILURE() << name << ": not an InputError: " << e.what();
    }
}

void expect_vtp_error(const TempDir& dir, const std::string& bytes, const std::string& expected)
{
    expect_input_error(dir, "bad.vtp", bytes, expected, [](const fs::path& p) { read_vtp_labelled(p); });
}

std::string replace_first(std::string text, const std::string& from, const std::string& to)
{
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
    return text;
}

// Where the appended bytes begin (just after '_').
size_t appended_start(const std::string& file) { return file.find('_', file.find("<AppendedData")) + 1; }

template <typename T>
void put_at(std::string& bytes, size_t at, T v)
{
    std::memcpy(bytes.data() + at, &v, sizeof v);
}

// ---------------------------------------------------------------------------
// Surfaces.

TEST(VtkXml, ReadsASurfaceAndItsLabelsInEveryEncoding)
{
    const TempDir tmp;
    const PolyMesh sphere = bumpy_sphere();
    const std::vector<int32_t> labels = face_labels(sphere.faces.size());
    for (Options o : test::vtk::all_options())
        for (bool narrow : {false, true}) {
            o.float32_points = narrow;
            o.int32_indices = narrow;
            o.block_size = 1000; // several blocks, the last one partial
            const std::string what = test::vtk::name(o) + (narrow ? " Float32/Int32" : " Float64/Int64");
            const fs::path path = tmp.path / "sphere.vtp";
            write(path, test::vtk::vtp(sphere, o, labels));
            const LabelledSurface read = read_vtp_labelled(path);
            expect_same_surface(read.mesh, sphere, narrow, what);
            EXPECT_EQ(read.labels.per_triangle, labels) << what;
            EXPECT_EQ(read.labels.source, "cell array ModelFaceID") << what;
            EXPECT_TRUE(read.mesh.triangle_patch.empty()) << what;
            // read_vtp and read_surface give the same mesh.
            const SurfaceMesh plain = read_surface(path);
            EXPECT_EQ(plain.triangles, read.mesh.triangles) << what;
            EXPECT_EQ(plain.points.size(), read.mesh.points.size()) << what;
        }
}

TEST(VtkXml, CompressedBlocksOfEverySizeReadBack)
{
    // A whole last block (last size 0) and a single block larger than the data.
    const TempDir tmp;
    const PolyMesh sphere = bumpy_sphere();
    for (size_t block : {size_t{8}, size_t{24}, size_t{1} << 20}) {
        Options o{Encoding::AppendedRaw, true};
        o.block_size = block;
        write(tmp.path / "s.vtp", test::vtk::vtp(sphere, o));
        expect_same_surface(read_vtp(tmp.path / "s.vtp"), sphere, false, "block size " + std::to_string(block));
    }
}

TEST(VtkXml, CarriesPolygonLabelsThroughFansAndDroppedTriangles)
{
    const TempDir tmp;
    PolyMesh cube = test::quad_cube();
    // A sliver triangle whose corners weld to two points: dropped with its label.
    cube.points.push_back(cube.points[0]);
    cube.faces.insert(cube.faces.begin() + 2, {0, 8, 1});
    const std::vector<int32_t> labels{1, 2, 99, 3, 4, 5, 6};
    for (const Options& o : test::vtk::all_options()) {
        write(tmp.path / "cube.vtp", test::vtk::vtp(cube, o, labels, "CellEntityIds"));
        const LabelledSurface read = read_vtp_labelled(tmp.path / "cube.vtp");
        ASSERT_EQ(read.mesh.triangles.size(), 12u) << test::vtk::name(o);
        EXPECT_EQ(read.labels.per_triangle, (std::vector<int32_t>{1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6}))
            << test::vtk::name(o);
        EXPECT_EQ(read.labels.source, "cell array CellEntityIds");
        EXPECT_EQ(read.mesh.points.size(), 8u);
        EXPECT_NEAR(signed_volume(read.mesh), 8.0, 1e-12);
    }
}

TEST(VtkXml, ChoosesTheLabelArrayByName)
{
    const TempDir tmp;
    const PolyMesh cube = test::quad_cube();
    const Options ascii{Encoding::Ascii};
    const std::string base = test::vtk::vtp(cube, ascii, {1, 2, 3, 4, 5, 6}, "Unnamed");
    const auto with_cells = [&](const std::string& arrays) {
        return replace_first(test::vtk::vtp(cube, ascii), "<CellData>\n</CellData>", "<CellData>\n" + arrays + "</CellData>");
    };
    const auto array = [](const std::string& type, const std::string& name, const std::string& values) {
        return "<DataArray type=\"" + type + "\" Name=\"" + name + "\" format=\"ascii\">" + values + "</DataArray>\n";
    };
    const auto labels_of = [&](const std::string& text) {
        write(tmp.path / "c.vtp", text);
        return read_vtp_labelled(tmp.path / "c.vtp").labels;
    };
    // The only integer cell array, whatever its name.
    SurfaceLabels l = labels_of(base);
    EXPECT_EQ(l.source, "cell array Unnamed");
    EXPECT_EQ(l.per_triangle, (std::vector<int32_t>{1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6}));
    // ModelFaceID before CapID before CellEntityIds, whatever the order in the file.
    l = labels_of(with_cells(array("Int32", "CellEntityIds", "7 7 7 7 7 7") + array("UInt8", "CapID", "0 0 0 1 1 2") +
                             array("Int64", "ModelFaceID", "10 11 12 13 14 15")));
    EXPECT_EQ(l.source, "cell array ModelFaceID");
    EXPECT_EQ(l.per_triangle, (std::vector<int32_t>{10, 10, 11, 11, 12, 12, 13, 13, 14, 14, 15, 15}));
    l = labels_of(with_cells(array("Int32", "GroupIds", "7 7 7 7 7 7") + array("UInt8", "CapID", "0 0 0 1 1 2")));
    EXPECT_EQ(l.source, "cell array CapID");
    // Two integer arrays of other names: no labels. Float and vector arrays are not labels.
    l = labels_of(with_cells(array("Int32", "A", "1 1 1 1 1 1") + array("Int32", "B", "2 2 2 2 2 2")));
    EXPECT_TRUE(l.empty());
    EXPECT_TRUE(l.source.empty());
    l = labels_of(with_cells(array("Float32", "Area", "1 1 1 1 1 1") + array("Int16", "Region", "4 4 4 5 5 5")));
    EXPECT_EQ(l.source, "cell array Region");
    l = labels_of(with_cells(array("Float32", "ModelFaceID", "1 1 1 1 1 1")));
    EXPECT_TRUE(l.empty());
    // No cell data at all.
    l = labels_of(test::vtk::vtp(cube, ascii));
    EXPECT_TRUE(l.empty());
}

TEST(VtkXml, MergesPiecesAndTheirLabels)
{
    const TempDir tmp;
    const PolyMesh cube = test::quad_cube();
    const std::string file = test::vtk::vtp(cube, Options{Encoding::Ascii}, {1, 2, 3, 4, 5, 6});
    const size_t begin = file.find("<Piece"), end = file.find("</Piece>") + 9;
    // The second piece: the cube moved by 10 along x, its labels 11 to 16.
    std::string second = file.substr(begin, end - begin);
    second = replace_first(second, "\n1 2 3 4 5 6 \n", "\n11 12 13 14 15 16 \n");
    second = replace_first(second, "-1 -1 -1 1 -1 -1 -1 1 -1 1 1 -1 -1 -1 1 1 -1 1 -1 1 1 1 1 1",
                           "9 -1 -1 11 -1 -1 9 1 -1 11 1 -1 9 -1 1 11 -1 1 9 1 1 11 1 1");
    std::string two = file;
    two.insert(end, second);
    write(tmp.path / "two.vtp", two);
    const LabelledSurface read = read_vtp_labelled(tmp.path / "two.vtp");
    ASSERT_EQ(read.mesh.triangles.size(), 24u);
    EXPECT_EQ(read.mesh.points.size(), 16u);
    EXPECT_EQ(read.labels.per_triangle, (std::vector<int32_t>{1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 11, 11, 12, 12,
                                                              13, 13, 14, 14, 15, 15, 16, 16}));
    EXPECT_NEAR(signed_volume(read.mesh), 16.0, 1e-12);
    // A later piece without the label array of the first.
    std::string unlabelled = file.substr(begin, end - begin);
    unlabelled = replace_first(unlabelled, "Name=\"ModelFaceID\"", "Name=\"Other\"");
    two = file;
    two.insert(end, unlabelled);
    expect_vtp_error(tmp, two, "piece 1 has no integer cell array ModelFaceID");
}

TEST(VtkXml, RefusesLabelsThatDoNotFit)
{
    const TempDir tmp;
    const PolyMesh sphere = bumpy_sphere();
    std::vector<int32_t> labels = face_labels(sphere.faces.size());
    labels.pop_back();
    for (const Options& o : test::vtk::all_options())
        expect_vtp_error(tmp, test::vtk::vtp(sphere, o, labels), "values for " + std::to_string(sphere.faces.size()));
    // A UInt64 label beyond int32.
    const std::string big = test::vtk::vtp(test::quad_cube(), Options{Encoding::Ascii}, {1, 2, 3, 4, 5, 6});
    expect_vtp_error(tmp, replace_first(replace_first(big, "type=\"Int32\" Name=\"ModelFaceID\"", "type=\"UInt64\" Name=\"ModelFaceID\""), "1 2 3", "1 4294967296 3"),
                     "beyond the 32-bit integers");
}

TEST(VtkXml, RefusesNonFiniteCoordinatesInEveryEncoding)
{
    const TempDir tmp;
    for (const double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
        PolyMesh cube = test::quad_cube();
        cube.points[5].y = bad;
        for (const Options& o : test::vtk::all_options()) {
            if (o.encoding == Encoding::Ascii) continue; // text below
            expect_vtp_error(tmp, test::vtk::vtp(cube, o), "NaN or infinite");
        }
    }
    const std::string ascii = test::vtk::vtp(test::quad_cube(), Options{Encoding::Ascii});
    expect_vtp_error(tmp, replace_first(ascii, "-1 -1 -1", "-1 nan -1"), "NaN or infinite");
}

TEST(VtkXml, RefusesTruncatedAppendedData)
{
    const TempDir tmp;
    const PolyMesh sphere = bumpy_sphere();
    for (bool zlib : {false, true})
        for (Encoding e : {Encoding::AppendedRaw, Encoding::AppendedBase64}) {
            const std::string file = test::vtk::vtp(sphere, Options{e, zlib}, face_labels(sphere.faces.size()));
            const size_t start = appended_start(file);
            const size_t end = file.rfind("\n</AppendedData>");
            for (size_t cut : {start, start + 3, start + (end - start) / 3, start + (end - start) / 2, end - 9, end - 1})
                expect_vtp_error(tmp, file.substr(0, cut), "");
        }
}

TEST(VtkXml, RefusesSizesAndOffsetsBeyondTheFile)
{
    const TempDir tmp;
    const PolyMesh cube = test::quad_cube();
    for (bool h64 : {false, true}) {
        // Plain: the Points array's byte count (its first header word) of 4 GiB and more.
        const std::string plain = test::vtk::vtp(cube, Options{Encoding::AppendedRaw, false, h64});
        const size_t at = appended_start(plain);
        std::string bad = plain;
        h64 ? put_at<uint64_t>(bad, at, uint64_t{1} << 40) : put_at<uint32_t>(bad, at, 0xfffffff0u);
        expect_vtp_error(tmp, bad, "bytes, but at most");

        // Compressed: [blocks, block size, last size, sizes...].
        const std::string packed = test::vtk::vtp(cube, Options{Encoding::AppendedRaw, true, h64});
        const size_t w = h64 ? 8 : 4, packed_at = appended_start(packed);
        const auto set_word = [&](std::string s, size_t index, uint64_t v) {
            h64 ? put_at<uint64_t>(s, packed_at + w * index, v)
                : put_at<uint32_t>(s, packed_at + w * index, static_cast<uint32_t>(v));
            return s;
        };
        // A block size of 4 GiB: refused before any allocation.
        expect_vtp_error(tmp, set_word(set_word(packed, 1, 0xffffffffu), 2, 0), "more than zlib can pack");
        // A block count the file cannot hold.
        expect_vtp_error(tmp, set_word(packed, 0, 0x7fffffffu), "more than the file can hold");
        // A compressed size beyond the file.
        expect_vtp_error(tmp, set_word(packed, 3, 0x7fffffffu), "longer than the");
        // A last block larger than the blocks.
        expect_vtp_error(tmp, set_word(packed, 2, 40000), "larger than the blocks");
        // Announced sizes that do not add up to the 8 points.
        expect_vtp_error(tmp, set_word(packed, 2, 8 * 3 * 8 - 8), "decompress to 184 bytes");
    }
    // An offset past the end of the appended data.
    const std::string file = test::vtk::vtp(cube, Options{Encoding::AppendedRaw});
    expect_vtp_error(tmp, replace_first(file, "offset=\"0\"", "offset=\"99999\""), "past the end");
    expect_vtp_error(tmp, replace_first(file, "offset=\"0\"", "offset=\"-1\""), "not a count");
    expect_vtp_error(tmp, replace_first(file, "NumberOfPoints=\"8\"", "NumberOfPoints=\"800000000000\""),
                     "values take");
    expect_vtp_error(tmp, replace_first(file, "NumberOfPoints=\"8\"", "NumberOfPoints=\"9\""), "where 27 values");
    // Appended arrays without appended data, and appended data without the '_' marker.
    expect_vtp_error(tmp, file.substr(0, file.find("<AppendedData")) + "</VTKFile>\n", "no <AppendedData>");
    expect_vtp_error(tmp, replace_first(file, "\n   _", "\n   "), "'_' marker");
    expect_vtp_error(tmp, replace_first(file, "encoding=\"raw\"", "encoding=\"hex\""), "neither raw nor base64");
    expect_vtp_error(tmp,
                     replace_first(test::vtk::vtp(cube, Options{Encoding::AppendedRaw, true}), "vtkZLibDataCompressor",
                                   "vtkLZ4DataCompressor"),
                     "vtkLZ4DataCompressor");
    expect_vtp_error(tmp, replace_first(file, "LittleEndian", "MiddleEndian"), "byte_order");
    expect_vtp_error(tmp, replace_first(file, "UInt32\">", "UInt16\">"), "header_type");
}

// A zlib-compressed inline array of `payload` whose header announces
// `announced` bytes in one block.
std::string zlib_array(const std::string& name, const std::string& payload, size_t announced, int components)
{
    std::string header;
    for (uint32_t v : {1u, 32768u, static_cast<uint32_t>(announced)}) test::put(header, v, false);
    const std::string packed = test::vtk::zlib_compress(payload);
    test::put(header, static_cast<uint32_t>(packed.size()), false);
    return "<DataArray type=\"Float64\" Name=\"" + name + "\" NumberOfComponents=\"" + std::to_string(components) +
           "\" format=\"binary\">" + test::base64(header) + test::base64(packed) + "</DataArray>\n";
}

TEST(VtkXml, RefusesBlocksThatDoNotDecompressToTheirSize)
{
    const TempDir tmp;
    const PolyMesh cube = test::quad_cube();
    std::string ascii = test::vtk::vtp(cube, Options{Encoding::Ascii});
    ascii = replace_first(ascii, "header_type=\"UInt32\"", "header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\"");
    const size_t begin = ascii.find("<DataArray type=\"Float64\" Name=\"Points\"");
    const size_t end = ascii.find("</DataArray>", begin) + std::string("</DataArray>\n").size();
    std::string xyz;
    for (const Vec3& p : cube.points) test::put(xyz, p.x, false), test::put(xyz, p.y, false), test::put(xyz, p.z, false);
    const auto with_points = [&](const std::string& array) {
        std::string s = ascii;
        return s.replace(begin, end - begin, array);
    };
    // The right size reads (the ascii arrays beside it are not compressed).
    write(tmp.path / "ok.vtp", with_points(zlib_array("Points", xyz, xyz.size(), 3)));
    EXPECT_NEAR(signed_volume(read_vtp(tmp.path / "ok.vtp")), 8.0, 1e-12);
    // More data than announced, and less.
    expect_vtp_error(tmp, with_points(zlib_array("Points", xyz + "abcdefgh", xyz.size(), 3)), "does not decompress");
    expect_vtp_error(tmp, with_points(zlib_array("Points", xyz.substr(8), xyz.size(), 3)), "does not decompress");
    // Corrupt compressed bytes.
    std::string corrupt = zlib_array("Points", xyz, xyz.size(), 3);
    const size_t data_at = corrupt.find("\">") + 2 + 24; // past the 16-byte header's base64
    corrupt[data_at + 8] = corrupt[data_at + 8] == 'A' ? 'B' : 'A';
    corrupt[data_at + 9] = corrupt[data_at + 9] == 'Q' ? 'R' : 'Q';
    expect_vtp_error(tmp, with_points(corrupt), "");
}

TEST(VtkXml, SurvivesRandomCorruptions)
{
    const TempDir tmp;
    const PolyMesh cube = test::quad_cube();
    std::mt19937 rng(11);
    int refused = 0;
    for (const Options& o : test::vtk::all_options()) {
        const std::string good = test::vtk::vtp(cube, o, {1, 2, 3, 4, 5, 6});
        for (int trial = 0; trial < 40; ++trial) {
            std::string bad = good;
            const int edits = 1 + static_cast<int>(rng() % 4);
            for (int e = 0; e < edits; ++e) bad[rng() % bad.size()] = static_cast<char>(rng());
            if (trial % 5 == 0) bad.resize(rng() % bad.size());
            write(tmp.path / "r.vtp", bad);
            try {
                const LabelledSurface s = read_vtp_labelled(tmp.path / "r.vtp");
                EXPECT_TRUE(s.labels.empty() || s.labels.per_triangle.size() == s.mesh.triangles.size());
            } catch (const InputError&) {
                ++refused;
            } catch (const std::exception& e) {
                ADD_FAILURE() << test::vtk::name(o) << " trial " << trial << ": not an InputError: " << e.what();
            }
        }
    }
    EXPECT_GT(refused, 0);
}

TEST(VtkXml, ReadsTheSampleBifurcationWithItsCapLabels)
{
    // cases/make_vtk_inputs.py: a closed bifurcation, wall 1, planar caps 2
    // (parent, radius 3 at z = -20), 3 and 4 (branches, radius 2.2).
    const LabelledSurface s = read_vtp_labelled("cases/bifurcation_vtp/bifurcation.vtp");
    ASSERT_EQ(s.labels.per_triangle.size(), s.mesh.triangles.size());
    EXPECT_EQ(s.labels.source, "cell array ModelFaceID");
    std::map<std::pair<int32_t, int32_t>, int> edges;
    std::map<int32_t, double> area;
    for (size_t t = 0; t < s.mesh.triangles.size(); ++t) {
        const Triangle& tri = s.mesh.triangles[t];
        for (int c = 0; c < 3; ++c) ++edges[std::minmax(tri[c], tri[(c + 1) % 3])];
        const Vec3 &a = s.mesh.points[tri[0]], &b = s.mesh.points[tri[1]], &c = s.mesh.points[tri[2]];
        area[s.labels.per_triangle[t]] += 0.5 * norm(cross(b - a, c - a));
    }
    for (const auto& [edge, uses] : edges) ASSERT_EQ(uses, 2) << "closed and manifold";
    EXPECT_GT(signed_volume(s.mesh), 0.0);
    ASSERT_EQ(area.size(), 4u);
    // Polygonal disks a little smaller than the circles (0.8 mm edges).
    EXPECT_NEAR(area[2], std::numbers::pi * 9.0, 0.03 * std::numbers::pi * 9.0);
    EXPECT_NEAR(area[3], std::numbers::pi * 2.2 * 2.2, 0.03 * std::numbers::pi * 2.2 * 2.2);
    EXPECT_NEAR(area[4], area[3], 0.03 * area[3]);
    EXPECT_GT(area[1], 10 * area[2]);
    // The parent's cap lies in the plane z = -20.
    for (size_t t = 0; t < s.mesh.triangles.size(); ++t)
        if (s.labels.per_triangle[t] == 2) {
            for (int32_t v : s.mesh.triangles[t]) ASSERT_NEAR(s.mesh.points[v].z, -20.0, 1e-9);
        }
}

// ---------------------------------------------------------------------------
// Images.

// A 7 x 6 x 5 volume under a rotation (x -> y, y -> -x) with anisotropic
// spacing, values from `value(i, j, k)`.
template <typename T, typename F>
test::vtk::Volume<T> volume(const F& value)
{
    test::vtk::Volume<T> v;
    v.size = {7, 6, 5};
    v.origin = {-12.5, 30.25, 7.0};
    v.spacing = {0.5, 0.75, 1.25};
    v.direction = {0, -1, 0, 1, 0, 0, 0, 0, 1};
    for (int k = 0; k < v.size[2]; ++k)
        for (int j = 0; j < v.size[1]; ++j)
            for (int i = 0; i < v.size[0]; ++i) v.values.push_back(value(i, j, k));
    return v;
}

template <typename T>
openvdb::Vec3d world(const test::vtk::Volume<T>& v, int i, int j, int k)
{
    const double ijk[3] = {i * v.spacing[0], j * v.spacing[1], k * v.spacing[2]};
    openvdb::Vec3d out;
    for (int r = 0; r < 3; ++r)
        out[r] = v.origin[r] + v.direction[3 * r] * ijk[0] + v.direction[3 * r + 1] * ijk[1] + v.direction[3 * r + 2] * ijk[2];
    return out;
}

template <typename T>
void expect_frame(const openvdb::FloatGrid& grid, const test::vtk::Volume<T>& v, const std::string& what)
{
    EXPECT_EQ(grid.metaValue<openvdb::Vec3i>("image_size"), openvdb::Vec3i(v.size[0], v.size[1], v.size[2])) << what;
    for (int i : {0, v.size[0] - 1})
        for (int j : {0, v.size[1] - 1})
            for (int k : {0, v.size[2] - 1}) {
                const openvdb::Vec3d got = grid.transform().indexToWorld(openvdb::Coord(i, j, k));
                const openvdb::Vec3d want = world(v, i, j, k);
                for (int d = 0; d < 3; ++d) EXPECT_NEAR(got[d], want[d], 1e-12) << what << " axis " << d;
            }
}

TEST(VtkXml, ReadsImagesOfEveryTypeInEveryEncoding)
{
    const TempDir tmp;
    const auto labels = volume<uint8_t>([](int i, int j, int k) { return uint8_t((i + 2 * j + 3 * k) % 4); });
    const auto intensity = volume<int16_t>([](int i, int j, int k) { return int16_t(i * j * 37 - k * 300); });
    const auto level_set = volume<float>([](int i, int j, int k) {
        return float(std::sqrt((i - 3.1) * (i - 3.1) + (j - 2.7) * (j - 2.7) + (k - 2.2) * (k - 2.2)) - 1.9);
    });
    const fs::path path = tmp.path / "image.vti";
    for (Options o : test::vtk::all_options()) {
        o.block_size = 64;
        const std::string what = test::vtk::name(o);

        write(path, test::vtk::vti(labels, o));
        ImageImportParams p;
        p.labels = {2, 3};
        openvdb::FloatGrid::Ptr grid = read_image(path, p);
        expect_frame(*grid, labels, what + " uint8");
        size_t expected = 0;
        for (int k = 0; k < 5; ++k)
            for (int j = 0; j < 6; ++j)
                for (int i = 0; i < 7; ++i) {
                    const bool in = labels.values[static_cast<size_t>((k * 6 + j) * 7 + i)] >= 2;
                    expected += in;
                    EXPECT_EQ(grid->tree().isValueOn(openvdb::Coord(i, j, k)), in) << what << " uint8";
                }
        EXPECT_EQ(grid->activeVoxelCount(), expected) << what;

        write(path, test::vtk::vti(intensity, o, "CT"));
        p = {};
        p.threshold = 100.0;
        grid = read_image(path, p);
        expect_frame(*grid, intensity, what + " int16");
        expected = 0;
        for (int16_t value : intensity.values) expected += value > 100;
        EXPECT_EQ(grid->activeVoxelCount(), expected) << what << " int16";

        write(path, test::vtk::vti(level_set, o, "distance"));
        p = {};
        p.level_set = true;
        grid = read_image(path, p);
        expect_frame(*grid, level_set, what + " float32");
        EXPECT_EQ(grid->getGridClass(), openvdb::GRID_LEVEL_SET);
        for (int k = 0; k < 5; ++k)
            for (int j = 0; j < 6; ++j)
                for (int i = 0; i < 7; ++i)
                    ASSERT_EQ(std::bit_cast<uint32_t>(grid->tree().getValue(openvdb::Coord(i, j, k))),
                              std::bit_cast<uint32_t>(level_set.values[static_cast<size_t>((k * 6 + j) * 7 + i)]))
                        << what << " float32 voxel " << i << ' ' << j << ' ' << k;
    }
}

TEST(VtkXml, IsAnImageExtension)
{
    EXPECT_TRUE(is_image_file("a/b/Segmentation.VTI"));
    EXPECT_TRUE(is_image_file("x.vti"));
    EXPECT_FALSE(is_surface_file("x.vti"));
}

// NIfTI-1 (nifti1.h offsets) of uint8 voxels with an sform (RAS, float32).
std::string nifti(const std::array<int, 3>& size, const std::array<std::array<float, 4>, 3>& srow,
                  const std::array<float, 3>& pixdim, const std::vector<uint8_t>& voxels)
{
    std::string b(352, '\0');
    put_at<int32_t>(b, 0, 348);
    const int16_t dim[8] = {3, int16_t(size[0]), int16_t(size[1]), int16_t(size[2]), 1, 1, 1, 1};
    for (int i = 0; i < 8; ++i) put_at<int16_t>(b, 40 + 2 * static_cast<size_t>(i), dim[i]);
    put_at<int16_t>(b, 70, 2); // uint8
    put_at<int16_t>(b, 72, 8);
    put_at<float>(b, 76, 1.0f);
    for (int i = 0; i < 3; ++i) put_at<float>(b, 80 + 4 * static_cast<size_t>(i), pixdim[i]);
    put_at<float>(b, 108, 352.0f);
    put_at<float>(b, 112, 1.0f);
    b[123] = 2; // mm
    put_at<int16_t>(b, 254, 2); // sform_code: aligned
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) put_at<float>(b, 280 + 16 * static_cast<size_t>(r) + 4 * static_cast<size_t>(c), srow[r][c]);
    std::memcpy(b.data() + 344, "n+1\0", 4);
    return b + std::string(voxels.begin(), voxels.end());
}

TEST(VtkXml, AVtiLabelImageMeshesLikeTheSameMaskAsNifti)
{
    // A ball of label 1 in a rotated, anisotropic frame. ITK reads a NIfTI's
    // sform as RAS and negates x and y into LPS; VTK ImageData is taken as
    // written. So the NIfTI's sform is the .vti's frame with x and y negated,
    // F * [Direction * diag(Spacing) | Origin] with F = diag(-1, -1, 1), and
    // both then place every voxel at the same world position. The frame's
    // numbers are exact in float32, the sform's precision.
    const auto mask = volume<uint8_t>([](int i, int j, int k) {
        return uint8_t((i - 3) * (i - 3) + (j - 2.5) * (j - 2.5) + (k - 2) * (k - 2) < 5.5 ? 1 : 0);
    });
    std::array<std::array<float, 4>, 3> srow{};
    const double flip[3] = {-1, -1, 1};
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) srow[r][c] = static_cast<float>(flip[r] * mask.direction[3 * r + c] * mask.spacing[c]);
        srow[r][3] = static_cast<float>(flip[r] * mask.origin[r]);
    }
    const TempDir tmp;
    write(tmp.path / "mask.nii", nifti(mask.size, srow, {0.5f, 0.75f, 1.25f}, mask.values));
    const openvdb::FloatGrid::Ptr from_nifti = read_image(tmp.path / "mask.nii");
    const double nifti_volume = signed_volume(marching_cubes(*from_nifti));
    ASSERT_GT(nifti_volume, 0.0);

    Options raw_zlib{Encoding::AppendedRaw, true};
    Options base64{Encoding::AppendedBase64, true, true};
    Options inline_base64{Encoding::Binary, false};
    for (const Options& o : {raw_zlib, base64, inline_base64}) {
        const std::string what = test::vtk::name(o);
        write(tmp.path / "mask.vti", test::vtk::vti(mask, o));
        const openvdb::FloatGrid::Ptr from_vti = read_image(tmp.path / "mask.vti");
        EXPECT_EQ(from_vti->activeVoxelCount(), from_nifti->activeVoxelCount()) << what;
        EXPECT_GT(from_vti->activeVoxelCount(), 10u);
        for (auto it = from_nifti->cbeginValueOn(); it; ++it)
            EXPECT_TRUE(from_vti->tree().isValueOn(it.getCoord())) << what;
        for (int i = 0; i < mask.size[0]; ++i)
            for (int j = 0; j < mask.size[1]; ++j)
                for (int k = 0; k < mask.size[2]; ++k) {
                    const openvdb::Vec3d a = from_nifti->transform().indexToWorld(openvdb::Coord(i, j, k));
                    const openvdb::Vec3d b = from_vti->transform().indexToWorld(openvdb::Coord(i, j, k));
                    ASSERT_NEAR((a - b).length(), 0.0, 1e-9) << what << " voxel " << i << ' ' << j << ' ' << k;
                }
        EXPECT_NEAR(signed_volume(marching_cubes(*from_vti)), nifti_volume, 1e-9) << what;
        EXPECT_EQ(from_vti->metaValue<openvdb::Vec3i>("image_size"), from_nifti->metaValue<openvdb::Vec3i>("image_size"));
    }
}

TEST(VtkXml, MovesTheOriginToAnExtentThatDoesNotStartAtZero)
{
    const TempDir tmp;
    auto v = volume<uint8_t>([](int i, int, int) { return uint8_t(i == 2); });
    const std::string file = test::vtk::vti(v, Options{Encoding::Ascii});
    // The same voxels at VTK indices 10..16, 0..5, -3..1.
    const std::string shifted = replace_first(replace_first(file, "WholeExtent=\"0 6 0 5 0 4\"", "WholeExtent=\"10 16 0 5 -3 1\""),
                                              "Extent=\"0 6 0 5 0 4\"", "Extent=\"10 16 0 5 -3 1\"");
    write(tmp.path / "s.vti", shifted);
    const openvdb::FloatGrid::Ptr grid = read_image(tmp.path / "s.vti");
    // Grid voxel (0, 0, 0) is VTK index (10, 0, -3): origin + D * S * (10, 0, -3).
    const openvdb::Vec3d first = grid->transform().indexToWorld(openvdb::Coord(0, 0, 0));
    const openvdb::Vec3d want{v.origin[0] - 0.0, v.origin[1] + 10 * 0.5, v.origin[2] - 3 * 1.25};
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(first[d], want[d], 1e-12);
    EXPECT_EQ(grid->activeVoxelCount(), 6u * 5u);
}

void expect_vti_error(const TempDir& dir, const std::string& bytes, const std::string& expected)
{
    expect_input_error(dir, "bad.vti", bytes, expected, [](const fs::path& p) { read_image(p); });
}

TEST(VtkXml, RefusesMalformedImages)
{
    const TempDir tmp;
    const auto v = volume<uint8_t>([](int i, int j, int) { return uint8_t(i == j); });
    const std::string ascii = test::vtk::vti(v, Options{Encoding::Ascii});
    const std::string packed = test::vtk::vti(v, Options{Encoding::AppendedRaw, true});
    expect_vti_error(tmp, replace_first(ascii, "Spacing=\"0.5", "Spacing=\"-0.5"), "positive");
    expect_vti_error(tmp, replace_first(ascii, "Spacing=\"0.5", "Spacing=\"nan"), "finite");
    expect_vti_error(tmp, replace_first(ascii, "Direction=\"0 -1 0", "Direction=\"0 -1"), "instead of 9");
    expect_vti_error(tmp, replace_first(ascii, "Direction=\"0 -1 0 1 0 0", "Direction=\"0 -1 0 0 -1 0"), "singular");
    expect_vti_error(tmp, replace_first(ascii, "WholeExtent=\"0 6", "WholeExtent=\"6 0"), "empty");
    expect_vti_error(tmp, replace_first(ascii, "WholeExtent=\"0 6 0 5 0 4\"", "WholeExtent=\"0 99999 0 99999 0 4\""),
                     "more than 2^31");
    expect_vti_error(tmp,
                     replace_first(replace_first(ascii, "WholeExtent=\"0 6 0 5 0 4\"", "WholeExtent=\"0 7 0 5 0 4\""),
                                   "Extent=\"0 6 0 5 0 4\"", "Extent=\"0 7 0 5 0 4\""),
                     "values where 240");
    expect_vti_error(tmp, replace_first(ascii, "Extent=\"0 6 0 5 0 4\">", "Extent=\"0 6 0 5 1 4\">"),
                     "not its WholeExtent");
    expect_vti_error(tmp, replace_first(ascii, "<PointData Scalars=\"labels\">", "<PointData Scalars=\"other\">"),
                     "no array of that name");
    expect_vti_error(tmp, replace_first(replace_first(ascii, "<PointData", "<CellData"), "</PointData>\n<CellData>\n</CellData>",
                                                    "</CellData>\n<PointData>\n</PointData>"),
                     "cell data");
    expect_vti_error(tmp, replace_first(ascii, "Name=\"labels\"", "Name=\"labels\" NumberOfComponents=\"2\""), "");
    expect_vti_error(tmp, replace_first(ascii, "</ImageData>", "<Piece Extent=\"0 6 0 5 0 4\"></Piece></ImageData>"),
                     "2 pieces");
    expect_vti_error(tmp, replace_first(ascii, "type=\"ImageData\"", "type=\"PolyData\""), "not VTK ImageData");
    // Damaged data: a truncated file, a block size of 4 GiB, no voxel inside.
    const size_t at = appended_start(packed);
    expect_vti_error(tmp, packed.substr(0, at + 20), "");
    std::string huge = packed;
    put_at<uint32_t>(huge, at + 4, 0xffffffffu);
    put_at<uint32_t>(huge, at + 8, 0);
    expect_vti_error(tmp, huge, "more than zlib can pack");
    expect_vti_error(tmp, test::vtk::vti(volume<uint8_t>([](int, int, int) { return uint8_t(0); }), Options{}),
                     "no nonzero voxel");
    auto nan = volume<float>([](int, int, int) { return 1.0f; });
    nan.values[17] = std::nanf("");
    expect_vti_error(tmp, test::vtk::vti(nan, Options{Encoding::Binary, true}), "NaN or infinite voxel");
}

TEST(VtkXml, ImagesSurviveRandomCorruptions)
{
    const TempDir tmp;
    const auto v = volume<int16_t>([](int i, int j, int k) { return int16_t(i + j - k); });
    std::mt19937 rng(5);
    for (const Options& o : test::vtk::all_options()) {
        const std::string good = test::vtk::vti(v, o);
        for (int trial = 0; trial < 30; ++trial) {
            std::string bad = good;
            for (int e = 0; e < 1 + static_cast<int>(rng() % 3); ++e) bad[rng() % bad.size()] = static_cast<char>(rng());
            if (trial % 4 == 0) bad.resize(rng() % bad.size());
            write(tmp.path / "r.vti", bad);
            try {
                read_image(tmp.path / "r.vti");
            } catch (const InputError&) {
            } catch (const std::exception& e) {
                ADD_FAILURE() << test::vtk::name(o) << " trial " << trial << ": not an InputError: " << e.what();
            }
        }
    }
}

} // namespace
} // namespace scalemesh
