// fuzz_seeds OUTPUT_DIR PROJECT_ROOT: writes the seed corpus of every fuzz
// target into OUTPUT_DIR/<kind>/, from the real files in
// PROJECT_ROOT/../shared/data (cut down to a few kilobytes, so that mutations
// stay fast), the sample cases' scalemesh.toml, a phantom, and tiny files
// written by hand in every variant each format has (docs/fuzzing.md).

#include "exporters/surface_writers.h"
#include "importers/stl_importer.h"
#include "importers/surface_files.h"
#include "importers/vdb_importer.h"
#include "importers/vtk_xml_writer.h"
#include "phantom/phantom.h"

#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <zlib.h>

#include <bit>
#include <cstring>
#include <iostream>
#include <sstream>

namespace {

namespace fs = std::filesystem;
using namespace scalemesh;
using scalemesh::test::PolyMesh;

std::string gzip(const std::string& bytes)
{
    z_stream z{};
    deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY); // 15 + 16: gzip wrapper
    std::string out(deflateBound(&z, static_cast<uLong>(bytes.size())) + 32, '\0');
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data()));
    z.avail_in = static_cast<uInt>(bytes.size());
    z.next_out = reinterpret_cast<Bytef*>(out.data());
    z.avail_out = static_cast<uInt>(out.size());
    deflate(&z, Z_FINISH);
    out.resize(z.total_out);
    deflateEnd(&z);
    return out;
}

// gunzip for .gz, inflate for a zlib stream (MetaImage's compressed data).
std::string inflate_all(const std::string& bytes, bool gzip_wrapper)
{
    z_stream z{};
    inflateInit2(&z, gzip_wrapper ? 15 + 16 : 15);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data()));
    z.avail_in = static_cast<uInt>(bytes.size());
    std::string out;
    std::string chunk(1 << 16, '\0');
    int status = Z_OK;
    while (status == Z_OK) {
        z.next_out = reinterpret_cast<Bytef*>(chunk.data());
        z.avail_out = static_cast<uInt>(chunk.size());
        status = inflate(&z, Z_NO_FLUSH);
        out.append(chunk.data(), chunk.size() - z.avail_out);
    }
    inflateEnd(&z);
    if (status != Z_STREAM_END) throw std::runtime_error("corrupt compressed data in a seed source");
    return out;
}

std::string zlib(const std::string& bytes)
{
    uLongf length = compressBound(static_cast<uLong>(bytes.size()));
    std::string out(length, '\0');
    compress(reinterpret_cast<Bytef*>(out.data()), &length, reinterpret_cast<const Bytef*>(bytes.data()),
             static_cast<uLong>(bytes.size()));
    out.resize(length);
    return out;
}

template <typename T>
void put(std::string& bytes, size_t offset, T v)
{
    std::memcpy(bytes.data() + offset, &v, sizeof v);
}

template <typename T>
T get(const std::string& bytes, size_t offset)
{
    T v;
    std::memcpy(&v, bytes.data() + offset, sizeof v);
    return v;
}

// A labelled 6 x 5 x 4 block: a 2 x 3 x 2 box of ones (and one voxel of label
// 2) inside zeros, so that every reader finds something inside.
std::string tiny_labels()
{
    std::string v(6 * 5 * 4, '\0');
    for (int z = 1; z < 3; ++z)
        for (int y = 1; y < 4; ++y)
            for (int x = 2; x < 4; ++x) v[static_cast<size_t>((z * 5 + y) * 6 + x)] = 1;
    v[0] = 2;
    return v;
}

// NIfTI-1 header (nifti1.h offsets) for uint8 data of the given size.
std::string nifti_header(int nx, int ny, int nz, float spacing)
{
    std::string h(352, '\0');
    put<int32_t>(h, 0, 348);
    const int16_t dim[8] = {3, static_cast<int16_t>(nx), static_cast<int16_t>(ny), static_cast<int16_t>(nz), 1, 1, 1, 1};
    for (int i = 0; i < 8; ++i) put<int16_t>(h, 40 + 2 * static_cast<size_t>(i), dim[i]);
    put<int16_t>(h, 70, 2); // uint8
    put<int16_t>(h, 72, 8);
    put<float>(h, 76, 1.0f);
    for (int i = 0; i < 3; ++i) put<float>(h, 80 + 4 * static_cast<size_t>(i), spacing);
    put<float>(h, 108, 352.0f);
    put<float>(h, 112, 1.0f);
    h[123] = 2; // mm
    put<int16_t>(h, 252, 1); // qform: scanner
    std::memcpy(h.data() + 344, "n+1\0", 4);
    return h;
}

class SeedWriter {
public:
    SeedWriter(fs::path out, fs::path root) : out_(std::move(out)), root_(std::move(root))
    {
        fs::create_directories(out_);
    }

    void write(const std::string& kind, const std::string& name, const std::string& bytes)
    {
        fs::create_directories(out_ / kind);
        test::write_text(out_ / kind / name, bytes);
    }
    fs::path data(const std::string& name) const { return root_ / ".." / "shared" / "data" / name; }
    const fs::path& root() const { return root_; }
    fs::path scratch(const std::string& name) const { return out_ / name; }

private:
    fs::path out_, root_;
};

void vdb_seeds(SeedWriter& seeds)
{
    PhantomParams params;
    params.voxel_size = 5.0; // a few hundred voxels
    openvdb::FloatGrid::Ptr label = voxelize(*make_shape("sphere", params.voxel_size), params);
    openvdb::FloatGrid::Ptr level_set = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(3.0f, {}, 1.0f, 2.0f);
    openvdb::Int32Grid::Ptr labels = openvdb::Int32Grid::create(0);
    labels->setName("labels");
    labels->tree().setValue({1, 2, 3}, 7);
    labels->tree().setValue({9, 2, 3}, 2);
    // Compressed only: uncompressed, every internal node's table of 32^3
    // values makes the file megabytes long.
    const std::pair<const char*, uint32_t> compressions[] = {
        {"zip", openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK},
        {"blosc", openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK}};
    for (const auto& [name, compression] : compressions) {
        const fs::path path = seeds.scratch("seed.vdb");
        openvdb::io::File file(path.string());
        file.setCompression(compression);
        file.write(openvdb::GridCPtrVec{label, level_set, labels});
        file.close();
        seeds.write("vdb", std::string("phantom_") + name + ".vdb", test::read_text(path));
        fs::remove(path);
    }
}

void nifti_seeds(SeedWriter& seeds)
{
    // The real mask's header with its first two slices (the mask touches z = 0).
    const std::string mask = inflate_all(test::read_text(seeds.data("ts_aorta_mask.nii.gz")), true);
    const auto offset = static_cast<size_t>(get<float>(mask, 108));
    const size_t slice = static_cast<size_t>(get<int16_t>(mask, 42)) * static_cast<size_t>(get<int16_t>(mask, 44)) *
                         static_cast<size_t>(get<int16_t>(mask, 72) / 8);
    std::string cut = mask.substr(0, offset + 2 * slice);
    put<int16_t>(cut, 46, 2);
    seeds.write("nifti", "aorta_two_slices.nii", cut);
    seeds.write("nifti", "aorta_two_slices.nii.gz", gzip(cut));
    const std::string tiny = nifti_header(6, 5, 4, 1.5f) + tiny_labels();
    seeds.write("nifti", "tiny.nii", tiny);
    seeds.write("nifti", "tiny.nii.gz", gzip(tiny));
}

void nrrd_seeds(SeedWriter& seeds)
{
    const std::string header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 6 5 4\nspace: left-posterior-superior\n"
                               "space directions: (1.5,0,0) (0,1.5,0) (0,0,2)\nspace origin: (-3,2,10)\n"
                               "endian: little\n";
    seeds.write("nrrd", "tiny_raw.nrrd", header + "encoding: raw\n\n" + tiny_labels());
    seeds.write("nrrd", "tiny_gzip.nrrd", header + "encoding: gzip\n\n" + gzip(tiny_labels()));
    std::string text;
    for (char v : tiny_labels()) text += std::to_string(static_cast<int>(v)) + ' ';
    seeds.write("nrrd", "tiny_ascii.nrrd", header + "encoding: ascii\n\n" + text + "\n");
    std::string floats;
    for (char v : tiny_labels()) floats += std::string(std::bit_cast<std::array<char, 4>>(v ? -1.0f : 1.0f).data(), 4);
    seeds.write("nrrd", "tiny_float.nrrd",
                "NRRD0004\ntype: float\ndimension: 3\nsizes: 6 5 4\nspacings: 0.5 0.5 1\nendian: little\n"
                "encoding: raw\n\n" +
                    floats);
}

void metaimage_seeds(SeedWriter& seeds)
{
    // The real level set sampled at every 8th voxel across and every 4th
    // along z: 20 x 50 x 9 floats, its header kept.
    const std::string file = test::read_text(seeds.data("vmtk_aorta_levelset.mha"));
    const std::string end_of_header = "ElementDataFile = LOCAL\n";
    const size_t data_at = file.find(end_of_header) + end_of_header.size();
    const std::string voxels = inflate_all(file.substr(data_at), false);
    const int nx = 157, ny = 393, nz = 34, step_xy = 8, step_z = 4;
    const int sx = (nx + step_xy - 1) / step_xy, sy = (ny + step_xy - 1) / step_xy, sz = (nz + step_z - 1) / step_z;
    std::string sampled;
    for (int z = 0; z < nz; z += step_z)
        for (int y = 0; y < ny; y += step_xy)
            for (int x = 0; x < nx; x += step_xy)
                sampled += voxels.substr((static_cast<size_t>(z * ny + y) * nx + static_cast<size_t>(x)) * 4, 4);
    std::ostringstream header;
    header << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n%COMPRESSION%"
           << "TransformMatrix = -1 0 0 0 -1 0 0 0 1\nOffset = -156.445 -24.6094 0\n"
           << "ElementSpacing = " << 0.878906 * step_xy << ' ' << 0.878906 * step_xy << ' ' << 1.50009 * step_z
           << "\nDimSize = " << sx << ' ' << sy << ' ' << sz << "\nElementType = MET_FLOAT\n" << end_of_header;
    const auto with = [&header](const std::string& compression) {
        std::string h = header.str();
        return h.replace(h.find("%COMPRESSION%"), 13, compression);
    };
    const std::string packed = zlib(sampled);
    seeds.write("metaimage", "aorta_sampled.mha", with("CompressedData = False\n") + sampled);
    seeds.write("metaimage", "aorta_sampled_zlib.mha",
                with("CompressedData = True\nCompressedDataSize = " + std::to_string(packed.size()) + "\n") + packed);
    seeds.write("metaimage", "tiny.mha",
                "ObjectType = Image\nNDims = 3\nBinaryData = True\nCompressedData = False\nElementSpacing = 1 1 2\n"
                "DimSize = 6 5 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                    tiny_labels());
}

// The first `count` triangles of the real aorta STL, as a binary STL.
std::string aorta_stl_cut(const SeedWriter& seeds, uint32_t count)
{
    std::string stl = test::read_text(seeds.data("vmtk_aorta_capped.stl")).substr(0, 84 + 50 * size_t{count});
    put<uint32_t>(stl, 80, count);
    return stl;
}

std::string ascii_stl(const PolyMesh& m)
{
    std::ostringstream o;
    o << "solid seed\n";
    for (const auto& f : m.faces) {
        o << " facet normal 0 0 0\n  outer loop\n";
        for (int32_t i : f) o << "   vertex " << m.points[i].x << ' ' << m.points[i].y << ' ' << m.points[i].z << '\n';
        o << "  endloop\n endfacet\n";
    }
    o << "endsolid seed\n";
    return o.str();
}

void surface_seeds(SeedWriter& seeds)
{
    const std::string cut = aorta_stl_cut(seeds, 150);
    seeds.write("stl", "aorta_150_triangles.stl", cut);
    const fs::path cut_path = seeds.scratch("aorta.stl");
    test::write_text(cut_path, cut);
    const SurfaceMesh aorta = read_stl(cut_path);
    fs::remove(cut_path);

    const std::pair<const char*, PolyMesh> meshes[] = {
        {"aorta", test::from_surface(aorta)}, {"icosphere", test::icosphere(1)}, {"cube", test::quad_cube()}};
    for (const auto& [name, mesh] : meshes) {
        const std::string n = name;
        if (n != "cube") seeds.write("stl", n + "_ascii.stl", ascii_stl(mesh));
        seeds.write("ply", n + "_ascii.ply", test::ply_text(mesh, test::PlyFormat::Ascii));
        seeds.write("ply", n + "_little.ply", test::ply_text(mesh, test::PlyFormat::BinaryLittle));
        seeds.write("ply", n + "_big.ply", test::ply_text(mesh, test::PlyFormat::BinaryBig));
        seeds.write("obj", n + ".obj", test::obj_text(mesh));
        seeds.write("vtp", n + "_ascii.vtp", test::vtp_text(mesh, test::VtpFormat::Ascii));
        seeds.write("vtp", n + "_binary32.vtp", test::vtp_text(mesh, test::VtpFormat::Binary32));
        seeds.write("vtp", n + "_binary64.vtp", test::vtp_text(mesh, test::VtpFormat::Binary64Separate));
        seeds.write("msh", n + "_22.msh", test::msh_text(mesh));
    }
    // MSH 4.1, ASCII and binary, as Gmsh writes it.
    for (const bool binary : {false, true}) {
        const fs::path path = seeds.scratch("seed.msh");
        SurfaceWriteOptions options;
        options.msh_binary = binary;
        write_surface(aorta, {}, path, options);
        seeds.write("msh", binary ? "aorta_41_binary.msh" : "aorta_41.msh", test::read_text(path));
        fs::remove(path);
    }
}

// VTK XML: .vtp surfaces with face labels and .vti images, in every
// encoding (tests/importers/vtk_xml_writer.h); small blocks, so that the
// compressed ones have several.
void vtk_xml_seeds(SeedWriter& seeds)
{
    const PolyMesh cube = test::quad_cube(), sphere = test::icosphere(1);
    std::vector<int32_t> sphere_labels(sphere.faces.size());
    for (size_t i = 0; i < sphere_labels.size(); ++i) sphere_labels[i] = static_cast<int32_t>(i % 4) + 1;
    test::vtk::Volume<uint8_t> labels;
    labels.size = {6, 5, 4};
    labels.spacing = {1.5, 1.5, 2};
    labels.direction = {0, -1, 0, 1, 0, 0, 0, 0, 1};
    for (char v : tiny_labels()) labels.values.push_back(static_cast<uint8_t>(v));
    test::vtk::Volume<int16_t> intensity;
    intensity.size = labels.size;
    intensity.origin = {-3, 2, 10};
    intensity.spacing = {0.5, 0.5, 1};
    test::vtk::Volume<float> level_set;
    level_set.size = labels.size;
    for (uint8_t v : labels.values) {
        intensity.values.push_back(static_cast<int16_t>(v * 400 - 100));
        level_set.values.push_back(v ? -1.0f : 1.0f);
    }
    for (test::vtk::Options o : test::vtk::all_options()) {
        o.block_size = 64;
        const std::string n = test::vtk::name(o);
        seeds.write("vtp", "cube_labels_" + n + ".vtp", test::vtk::vtp(cube, o, {1, 2, 3, 4, 5, 6}));
        seeds.write("vti", "labels_" + n + ".vti", test::vtk::vti(labels, o));
    }
    for (const test::vtk::Options& o : {test::vtk::Options{test::vtk::Encoding::AppendedRaw, true},
                                        test::vtk::Options{test::vtk::Encoding::AppendedBase64, true, true}}) {
        seeds.write("vtp", "icosphere_labels_" + test::vtk::name(o) + ".vtp",
                    test::vtk::vtp(sphere, o, sphere_labels, "CellEntityIds"));
        seeds.write("vti", "intensity_" + test::vtk::name(o) + ".vti", test::vtk::vti(intensity, o, "CT"));
        seeds.write("vti", "level_set_" + test::vtk::name(o) + ".vti", test::vtk::vti(level_set, o, "distance"));
    }
}

void case_seeds(SeedWriter& seeds)
{
    for (const auto& entry : fs::directory_iterator(seeds.root() / "cases"))
        if (fs::exists(entry.path() / "scalemesh.toml"))
            seeds.write("case", entry.path().filename().string() + ".toml",
                        test::read_text(entry.path() / "scalemesh.toml"));
}

} // namespace

int main(int argc, char** argv)
{
    if (argc != 3) {
        std::cerr << "usage: fuzz_seeds OUTPUT_DIR PROJECT_ROOT\n";
        return 2;
    }
    try {
        openvdb::initialize();
        fs::remove_all(argv[1]);
        SeedWriter seeds(argv[1], argv[2]);
        vdb_seeds(seeds);
        nifti_seeds(seeds);
        nrrd_seeds(seeds);
        metaimage_seeds(seeds);
        surface_seeds(seeds);
        vtk_xml_seeds(seeds);
        case_seeds(seeds);
    } catch (const std::exception& e) {
        std::cerr << "fuzz_seeds: " << e.what() << '\n';
        return 1;
    }
    return 0;
}
