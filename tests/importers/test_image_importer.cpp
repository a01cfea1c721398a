// Reading NIfTI, NRRD and MetaImage files: the real aorta files in
// ../shared/data land where their headers say, with the voxel counts their
// data hold (both counted here from the raw bytes, without ITK); files
// written here with known content check direction, spacing, labels and
// threshold; malformed and randomly corrupted files are refused with a
// scalemesh::Error, never a crash.

#include "core/errors.h"
#include "core/surface_mesh.h"
#include "importers/image_importer.h"
#include "isosurface/marching_cubes.h"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <zlib.h>

#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <sstream>

// ITK 5.2's NRRD and MetaImage readers leak their parse structures when they
// refuse a file (itk_nrrdNew, itk_biffGet, MetaImage::ReadStream); under
// AddressSanitizer, LeakSanitizer would fail the run for ITK's leaks.
extern "C" const char* __lsan_default_suppressions() { return "leak:libITKNrrdIO\nleak:libITKMetaIO\n"; }

namespace scalemesh {
namespace {

namespace fs = std::filesystem;

const fs::path kMask = "../shared/data/ts_aorta_mask.nii.gz";
const fs::path kLevelSet = "../shared/data/vmtk_aorta_levelset.mha";

struct Scratch {
    fs::path dir = fs::temp_directory_path() / ("scalemesh-image-" + std::to_string(std::random_device{}()));
    Scratch() { fs::create_directories(dir); }
    ~Scratch()
    {
        std::error_code ignored;
        fs::remove_all(dir, ignored);
    }
};

using Mat3 = std::array<std::array<double, 3>, 3>;

std::string file_bytes(const fs::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& path, const std::string& bytes)
{
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::string gunzip_file(const fs::path& path)
{
    gzFile f = gzopen(path.string().c_str(), "rb");
    EXPECT_NE(f, nullptr) << path;
    std::string out;
    char buffer[1 << 16];
    for (int n; (n = gzread(f, buffer, sizeof buffer)) > 0;) out.append(buffer, static_cast<size_t>(n));
    gzclose(f);
    return out;
}

void write_gz(const fs::path& path, const std::string& bytes)
{
    gzFile f = gzopen(path.string().c_str(), "wb");
    gzwrite(f, bytes.data(), static_cast<unsigned>(bytes.size()));
    gzclose(f);
}

template <typename T>
T get(const std::string& bytes, size_t offset)
{
    T v;
    std::memcpy(&v, bytes.data() + offset, sizeof v);
    return v;
}

template <typename T>
void put(std::string& bytes, size_t offset, T v)
{
    std::memcpy(bytes.data() + offset, &v, sizeof v);
}

template <typename T>
std::string raw(const std::vector<T>& values)
{
    return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

// NIfTI-1, little-endian, field offsets from nifti1.h.
struct Nifti {
    std::array<int16_t, 8> dim{};
    int16_t datatype = 2; // 2 uint8, 4 int16, 16 float32
    int16_t bitpix = 8;
    std::array<float, 3> pixdim{1, 1, 1};
    int16_t qform_code = 0, sform_code = 0;
    std::array<std::array<float, 4>, 3> srow{};
    std::string data;

    std::string bytes() const
    {
        std::string b(352, '\0');
        put<int32_t>(b, 0, 348);
        for (int i = 0; i < 8; ++i) put<int16_t>(b, 40 + 2 * i, dim[i]);
        put<int16_t>(b, 70, datatype);
        put<int16_t>(b, 72, bitpix);
        put<float>(b, 76, 1.0f); // qfac
        for (int i = 0; i < 3; ++i) put<float>(b, 80 + 4 * i, pixdim[i]);
        put<float>(b, 108, 352.0f); // vox_offset
        put<float>(b, 112, 1.0f);   // scl_slope
        b[123] = 2;                 // xyzt_units: mm
        put<int16_t>(b, 252, qform_code);
        put<int16_t>(b, 254, sform_code);
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) put<float>(b, 280 + 16 * r + 4 * c, srow[r][c]);
        std::memcpy(b.data() + 344, "n+1\0", 4);
        return b + data;
    }

    static Nifti parse(const std::string& b)
    {
        Nifti n;
        for (int i = 0; i < 8; ++i) n.dim[i] = get<int16_t>(b, 40 + 2 * i);
        n.datatype = get<int16_t>(b, 70);
        n.bitpix = get<int16_t>(b, 72);
        for (int i = 0; i < 3; ++i) n.pixdim[i] = get<float>(b, 80 + 4 * i);
        n.qform_code = get<int16_t>(b, 252);
        n.sform_code = get<int16_t>(b, 254);
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) n.srow[r][c] = get<float>(b, 280 + 16 * r + 4 * c);
        n.data = b.substr(static_cast<size_t>(get<float>(b, 108)));
        return n;
    }

    // ITK's world (LPS) position of voxel (i, j, k) through the sform, which
    // is in RAS: x and y change sign.
    openvdb::Vec3d world(double i, double j, double k) const
    {
        openvdb::Vec3d ras;
        for (int r = 0; r < 3; ++r) ras[r] = srow[r][0] * i + srow[r][1] * j + srow[r][2] * k + srow[r][3];
        return {-ras[0], -ras[1], ras[2]};
    }
};

// A sform with the given rotation (columns: axis directions in RAS), spacing
// and offset.
void set_sform(Nifti& n, const Mat3& rotation, const std::array<double, 3>& spacing,
               const std::array<double, 3>& offset)
{
    n.sform_code = 2;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) n.srow[r][c] = static_cast<float>(rotation[r][c] * spacing[c]);
        n.srow[r][3] = static_cast<float>(offset[r]);
    }
    for (int c = 0; c < 3; ++c) n.pixdim[c] = static_cast<float>(spacing[c]);
}

// A MetaImage header as key -> numbers, and the bytes after it.
struct Meta {
    std::map<std::string, std::vector<double>> fields;
    std::map<std::string, std::string> text;
    std::string data;

    static Meta parse(const std::string& bytes)
    {
        Meta m;
        std::istringstream in(bytes);
        std::string line;
        while (std::getline(in, line)) {
            const size_t eq = line.find(" = ");
            const std::string key = line.substr(0, eq), value = line.substr(eq + 3);
            m.text[key] = value;
            std::istringstream numbers(value);
            for (double v; numbers >> v;) m.fields[key].push_back(v);
            if (key == "ElementDataFile") break;
        }
        m.data = bytes.substr(static_cast<size_t>(in.tellg()));
        return m;
    }
};

std::string mha(const std::array<int, 3>& size, const std::array<double, 3>& spacing,
                const std::array<double, 3>& offset, const std::string& element_type, const std::string& data,
                const std::string& matrix = "1 0 0 0 1 0 0 0 1")
{
    std::ostringstream h;
    h << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nCompressedData = False\n"
      << "TransformMatrix = " << matrix << "\nOffset = " << offset[0] << ' ' << offset[1] << ' ' << offset[2]
      << "\nElementSpacing = " << spacing[0] << ' ' << spacing[1] << ' ' << spacing[2] << "\nDimSize = " << size[0]
      << ' ' << size[1] << ' ' << size[2] << "\nElementType = " << element_type << "\nElementDataFile = LOCAL\n";
    return h.str() + data;
}

// The same with zlib-compressed voxels.
std::string compressed_mha(const std::array<int, 3>& size, const std::string& element_type, const std::string& data)
{
    std::string packed(compressBound(static_cast<uLong>(data.size())), '\0');
    uLongf length = static_cast<uLongf>(packed.size());
    compress(reinterpret_cast<Bytef*>(packed.data()), &length, reinterpret_cast<const Bytef*>(data.data()),
             static_cast<uLong>(data.size()));
    packed.resize(length);
    std::string out = mha(size, {1, 1, 1}, {0, 0, 0}, element_type, packed);
    const std::string plain = "CompressedData = False\n";
    out.replace(out.find(plain), plain.size(),
                "CompressedData = True\nCompressedDataSize = " + std::to_string(packed.size()) + "\n");
    return out;
}

std::string nrrd(const std::string& sizes, const std::string& geometry, const std::string& type,
                 const std::string& data, int dimension = 3)
{
    return "NRRD0004\ntype: " + type + "\ndimension: " + std::to_string(dimension) + "\nsizes: " + sizes + "\n" +
           geometry + "endian: little\nencoding: raw\n\n" + data;
}

std::vector<openvdb::Coord> active_coords(const openvdb::FloatGrid& grid)
{
    std::vector<openvdb::Coord> out;
    for (auto it = grid.cbeginValueOn(); it; ++it) out.push_back(it.getCoord());
    return out;
}

openvdb::Vec3i image_size(const openvdb::FloatGrid& grid) { return grid.metaValue<openvdb::Vec3i>("image_size"); }

void expect_near(const openvdb::Vec3d& a, const openvdb::Vec3d& b, double tolerance, const std::string& what)
{
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(a[d], b[d], tolerance) << what << " axis " << d;
}

// ---------------------------------------------------------------------------
// The real files.

TEST(ImageImporter, ReadsTheAortaMaskWhereItsHeaderPutsIt)
{
    const Nifti header = Nifti::parse(gunzip_file(kMask));
    // With qform_code 0 and an orthonormal sform, ITK uses the sform.
    ASSERT_EQ(header.qform_code, 0);
    ASSERT_GT(header.sform_code, 0);
    ASSERT_EQ(header.datatype, 2); // uint8
    const std::array<int, 3> n{header.dim[1], header.dim[2], header.dim[3]};
    EXPECT_EQ(n, (std::array<int, 3>{120, 126, 164}));

    // Inside voxels and their world box, from the raw bytes.
    int64_t inside = 0;
    openvdb::Vec3d lo(1e300), hi(-1e300);
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i)
                if (header.data[static_cast<size_t>((k * n[1] + j) * n[0] + i)] != 0) {
                    ++inside;
                    const openvdb::Vec3d w = header.world(i, j, k);
                    lo = openvdb::math::minComponent(lo, w);
                    hi = openvdb::math::maxComponent(hi, w);
                }
    EXPECT_EQ(inside, 72810);

    const auto grid = read_image(kMask);
    EXPECT_EQ(grid->getGridClass(), openvdb::GRID_FOG_VOLUME);
    EXPECT_EQ(grid->getName(), "label");
    EXPECT_EQ(image_size(*grid), openvdb::Vec3i(n[0], n[1], n[2]));
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(grid->voxelSize()[d], header.pixdim[d], 1e-6);
    EXPECT_NEAR(header.pixdim[0], 1.5, 1e-6);
    EXPECT_EQ(grid->activeVoxelCount(), inside);
    for (auto it = grid->cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        ASSERT_EQ(*it, 1.0f);
        ASSERT_NE(header.data[static_cast<size_t>((c.z() * n[1] + c.y()) * n[0] + c.x())], 0) << c;
    }

    // The image's corners land where the header puts them.
    for (int corner = 0; corner < 8; ++corner) {
        const openvdb::Vec3d ijk((corner & 1) * (n[0] - 1), (corner >> 1 & 1) * (n[1] - 1),
                                 (corner >> 2 & 1) * (n[2] - 1));
        expect_near(grid->indexToWorld(ijk), header.world(ijk[0], ijk[1], ijk[2]), 1e-4, "corner");
    }
    // The world box of the inside voxels, as read, and within the image's box.
    openvdb::Vec3d glo(1e300), ghi(-1e300);
    for (const openvdb::Coord& c : active_coords(*grid)) {
        const openvdb::Vec3d w = grid->indexToWorld(c);
        glo = openvdb::math::minComponent(glo, w);
        ghi = openvdb::math::maxComponent(ghi, w);
    }
    expect_near(glo, lo, 1e-4, "inside box low");
    expect_near(ghi, hi, 1e-4, "inside box high");
    const openvdb::Vec3d a = header.world(0, 0, 0), b = header.world(n[0] - 1, n[1] - 1, n[2] - 1);
    for (int d = 0; d < 3; ++d) {
        EXPECT_GE(glo[d], std::min(a[d], b[d]) - 1e-4);
        EXPECT_LE(ghi[d], std::max(a[d], b[d]) + 1e-4);
    }
    // The mask touches the image slice z = 0 (its opening on the border).
    EXPECT_EQ(grid->evalActiveVoxelBoundingBox().min().z(), 0);

    const SurfaceFacts facts = surface_facts(marching_cubes(*grid));
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_GT(facts.signed_volume, 0.0);
}

TEST(ImageImporter, ReadsTheVmtkLevelSetWithAnisotropicVoxels)
{
    const Meta header = Meta::parse(file_bytes(kLevelSet));
    ASSERT_EQ(header.text.at("ElementType"), "MET_FLOAT");
    ASSERT_EQ(header.text.at("CompressedData"), "True");
    const auto& size = header.fields.at("DimSize");
    const auto& spacing = header.fields.at("ElementSpacing");
    const auto& offset = header.fields.at("Offset");
    const auto& matrix = header.fields.at("TransformMatrix");
    EXPECT_EQ(size, (std::vector<double>{157, 393, 34}));
    EXPECT_NEAR(spacing[0], 0.879, 1e-3);
    EXPECT_NEAR(spacing[1], 0.879, 1e-3);
    EXPECT_NEAR(spacing[2], 1.5, 1e-3);

    // The voxels, inflated with zlib.
    const size_t count = static_cast<size_t>(size[0] * size[1] * size[2]);
    std::vector<float> values(count);
    uLongf length = static_cast<uLongf>(count * sizeof(float));
    ASSERT_EQ(uncompress(reinterpret_cast<Bytef*>(values.data()), &length,
                         reinterpret_cast<const Bytef*>(header.data.data()), static_cast<uLong>(header.data.size())),
              Z_OK);
    ASSERT_EQ(length, count * sizeof(float));
    const int64_t negative = std::count_if(values.begin(), values.end(), [](float v) { return v < 0; });
    EXPECT_EQ(negative, 11590);

    const auto grid = read_image(kLevelSet, {.level_set = true});
    EXPECT_TRUE(is_level_set(*grid));
    EXPECT_EQ(image_size(*grid), openvdb::Vec3i(157, 393, 34));
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(grid->voxelSize()[d], spacing[d], 1e-9);
    // Every image voxel is kept, with its value.
    EXPECT_EQ(grid->activeVoxelCount(), static_cast<openvdb::Index64>(count));
    int64_t read_negative = 0;
    for (auto it = grid->cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        ASSERT_EQ(*it, values[static_cast<size_t>((c.z() * size[1] + c.y()) * size[0] + c.x())]) << c;
        read_negative += *it < 0;
    }
    EXPECT_EQ(read_negative, negative);
    EXPECT_GT(grid->background(), 0.0f);

    // MetaImage: world = Offset + sum over index axes d of TransformMatrix
    // row d * spacing d * index d.
    for (const openvdb::Vec3d ijk :
         {openvdb::Vec3d(0, 0, 0), openvdb::Vec3d(156, 392, 33), openvdb::Vec3d(10, 200, 7)}) {
        openvdb::Vec3d expected(offset[0], offset[1], offset[2]);
        for (int d = 0; d < 3; ++d)
            for (int w = 0; w < 3; ++w) expected[w] += matrix[3 * d + w] * spacing[d] * ijk[d];
        expect_near(grid->indexToWorld(ijk), expected, 1e-6, "voxel");
    }

    const SurfaceMesh surface = marching_cubes(*grid);
    const SurfaceFacts facts = surface_facts(surface);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.components, 1);
    EXPECT_GT(facts.signed_volume, 0.0);
    // The enclosed volume is near that of the negative voxels (an interpolated
    // surface, so not equal).
    const double voxel_volume = spacing[0] * spacing[1] * spacing[2];
    EXPECT_NEAR(facts.signed_volume / (static_cast<double>(negative) * voxel_volume), 1.0, 0.15);
}

// ---------------------------------------------------------------------------
// Files with known content.

Mat3 rotation(double angle, bool reflect)
{
    // 30 degrees about (1, 2, 2)/3, then optionally a mirror in x.
    const double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
    const double x = 1.0 / 3, y = 2.0 / 3, z = 2.0 / 3;
    Mat3 r{{{t * x * x + c, t * x * y - s * z, t * x * z + s * y},
            {t * x * y + s * z, t * y * y + c, t * y * z - s * x},
            {t * x * z - s * y, t * y * z + s * x, t * z * z + c}}};
    if (reflect)
        for (double& v : r[0]) v = -v;
    return r;
}

TEST(ImageImporter, PlacesARotatedNiftiVoxelWhereItsSformSays)
{
    const Scratch s;
    for (const bool reflect : {false, true}) {
        Nifti n;
        n.dim = {3, 10, 12, 14, 1, 1, 1, 1};
        set_sform(n, rotation(std::numbers::pi / 6, reflect), {0.8, 1.1, 1.7}, {12.5, -7.25, 30.0});
        n.data.assign(10 * 12 * 14, '\0');
        n.data[(5 * 12 + 4) * 10 + 3] = 1; // voxel (3, 4, 5)
        const fs::path file = s.dir / (reflect ? "mirrored.nii.gz" : "rotated.nii.gz");
        write_gz(file, n.bytes());

        const auto grid = read_image(file);
        const auto coords = active_coords(*grid);
        ASSERT_EQ(coords.size(), 1u);
        EXPECT_EQ(coords[0], openvdb::Coord(3, 4, 5));
        const openvdb::Vec3d expected = n.world(3, 4, 5);
        expect_near(grid->indexToWorld(coords[0]), expected, 1e-4, reflect ? "mirrored" : "rotated");
        for (int d = 0; d < 3; ++d) EXPECT_NEAR(grid->voxelSize()[d], n.pixdim[d], 1e-5);

        // The surface around the voxel is centred on it.
        const SurfaceMesh surface = marching_cubes(*grid);
        EXPECT_TRUE(surface_facts(surface).closed_manifold());
        openvdb::Vec3d centre(0.0);
        for (const Vec3& p : surface.points) centre += openvdb::Vec3d(p.x, p.y, p.z);
        centre /= static_cast<double>(surface.points.size());
        expect_near(centre, expected, 1e-4, "surface centre");
        // Volume of the octahedron marching cubes puts around one voxel: a
        // sixth of the voxel's volume, whatever its orientation. Its sign is
        // marching cubes' business: the mirrored image's transform has
        // determinant -1, which reverses the orientation of index space.
        const double voxel_volume = 0.8 * 1.1 * 1.7;
        const double volume = surface_facts(surface).signed_volume;
        EXPECT_NEAR(std::abs(volume), voxel_volume / 6, 1e-3 * voxel_volume);
        EXPECT_EQ(grid->transform().baseMap()->getAffineMap()->getMat4().det() < 0, reflect);
        if (!reflect) {
            EXPECT_GT(volume, 0.0);
        }
    }
}

TEST(ImageImporter, HonoursAnisotropicSpacingAndDirectionInNrrdAndMetaImage)
{
    const Scratch s;
    {
        // NRRD: a 5 x 5 x 3 block of voxels in a 9 x 7 x 5 image.
        std::vector<int16_t> v(9 * 7 * 5, 0);
        for (int z = 1; z <= 3; ++z)
            for (int y = 1; y <= 5; ++y)
                for (int x = 2; x <= 6; ++x) v[static_cast<size_t>((z * 7 + y) * 9 + x)] = 1;
        write_bytes(s.dir / "block.nrrd",
                    nrrd("9 7 5",
                         "space: left-posterior-superior\nspace directions: (0.5,0,0) (0,0.7,0) (0,0,1.2)\n"
                         "space origin: (10,20,30)\n",
                         "short", raw(v)));
        const auto grid = read_image(s.dir / "block.nrrd");
        EXPECT_EQ(grid->activeVoxelCount(), 75u);
        expect_near(grid->voxelSize(), {0.5, 0.7, 1.2}, 1e-12, "voxel size");
        EXPECT_EQ(image_size(*grid), openvdb::Vec3i(9, 7, 5));
        // The 0.5 iso surface lies half a voxel outside the block's voxel centres.
        Vec3 lo, hi;
        bounding_box(marching_cubes(*grid), lo, hi);
        expect_near({lo.x, lo.y, lo.z}, {10 + 1.5 * 0.5, 20 + 0.5 * 0.7, 30 + 0.5 * 1.2}, 1e-9, "low");
        expect_near({hi.x, hi.y, hi.z}, {10 + 6.5 * 0.5, 20 + 5.5 * 0.7, 30 + 3.5 * 1.2}, 1e-9, "high");
    }
    {
        // NRRD in RAS: ITK turns it into LPS.
        std::vector<uint8_t> v(4 * 4 * 4, 0);
        v[(2 * 4 + 1) * 4 + 3] = 1; // voxel (3, 1, 2)
        write_bytes(s.dir / "ras.nrrd",
                    nrrd("4 4 4",
                         "space: right-anterior-superior\nspace directions: (0,2,0) (-3,0,0) (0,0,0.5)\n"
                         "space origin: (1,2,3)\n",
                         "uchar", raw(v)));
        const auto grid = read_image(s.dir / "ras.nrrd");
        const openvdb::Vec3d ras(1 + 1 * -3.0, 2 + 3 * 2.0, 3 + 2 * 0.5);
        expect_near(grid->indexToWorld(openvdb::Coord(3, 1, 2)), {-ras[0], -ras[1], ras[2]}, 1e-9, "RAS voxel");
    }
    {
        // MetaImage: TransformMatrix holds the index axes' directions one
        // after the other; a quarter turn about z.
        std::vector<uint8_t> v(5 * 6 * 3, 0);
        v[(1 * 6 + 3) * 5 + 2] = 1; // voxel (2, 3, 1)
        write_bytes(s.dir / "turned.mha",
                    mha({5, 6, 3}, {0.4, 0.9, 2.0}, {1, 2, 3}, "MET_UCHAR", raw(v), "0 1 0 -1 0 0 0 0 1"));
        const auto grid = read_image(s.dir / "turned.mha");
        // x axis along +y, y axis along -x.
        const openvdb::Vec3d expected(1 - 3 * 0.9, 2 + 2 * 0.4, 3 + 1 * 2.0);
        expect_near(grid->indexToWorld(openvdb::Coord(2, 3, 1)), expected, 1e-9, "MetaImage voxel");
        expect_near(grid->voxelSize(), {0.4, 0.9, 2.0}, 1e-12, "voxel size");
    }
}

Nifti label_image()
{
    // 8^3, int16: label 1 in slices z 0-1, label 2 in slices 3-4, one voxel of 3.
    Nifti n;
    n.dim = {3, 8, 8, 8, 1, 1, 1, 1};
    n.datatype = 4;
    n.bitpix = 16;
    std::vector<int16_t> v(512, 0);
    for (int z = 0; z < 8; ++z)
        for (int i = 0; i < 64; ++i) v[static_cast<size_t>(z * 64 + i)] = z < 2 ? 1 : (z == 3 || z == 4) ? 2 : 0;
    v[7 * 64 + 9] = 3;
    n.data = raw(v);
    return n;
}

TEST(ImageImporter, SelectsAndMergesLabels)
{
    const Scratch s;
    const fs::path file = s.dir / "labels.nii";
    write_bytes(file, label_image().bytes());

    const auto two = read_image(file, {.labels = {2}});
    EXPECT_EQ(two->activeVoxelCount(), 128u);
    for (const openvdb::Coord& c : active_coords(*two)) EXPECT_TRUE(c.z() == 3 || c.z() == 4) << c;
    EXPECT_EQ(read_image(file, {.labels = {1, 2}})->activeVoxelCount(), 256u);
    EXPECT_EQ(read_image(file, {.labels = {3}})->activeVoxelCount(), 1u);
    EXPECT_EQ(read_image(file)->activeVoxelCount(), 257u); // any nonzero
    const auto merged = read_image(file, {.labels = {2, 3}});
    EXPECT_EQ(merged->tree().getValue(openvdb::Coord(1, 1, 7)), 1.0f);
    EXPECT_TRUE(merged->tree().isValueOn(openvdb::Coord(1, 1, 7)));
    EXPECT_FALSE(merged->tree().isValueOn(openvdb::Coord(1, 1, 0)));
    EXPECT_EQ(merged->tree().getValue(openvdb::Coord(1, 1, 0)), 0.0f);

    try {
        read_image(file, {.labels = {7}});
        FAIL() << "an absent label must be refused";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("label 7 not present"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("labels present: 0, 1, 2, 3"), std::string::npos) << e.what();
    }
    EXPECT_THROW(read_image(file, {.labels = {1}, .threshold = 0.5}), InputError);
    EXPECT_THROW(read_image(file, {.labels = {1}, .level_set = true}), InputError);
}

TEST(ImageImporter, ListsAtMostTenLabelsPresent)
{
    const Scratch s;
    std::vector<uint16_t> v(16 * 16 * 16);
    for (size_t i = 0; i < v.size(); ++i) v[i] = static_cast<uint16_t>(i % 40);
    write_bytes(s.dir / "many.nrrd", nrrd("16 16 16", "", "ushort", raw(v)));
    try {
        read_image(s.dir / "many.nrrd", {.labels = {100, 200}});
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("labels 100, 200 not present"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("0, 1, 2, 3, 4, 5, 6, 7, 8, 9, ..."), std::string::npos) << e.what();
    }
}

TEST(ImageImporter, ThresholdsAnIntensityImage)
{
    const Scratch s;
    std::vector<float> v(12 * 12 * 12);
    int64_t above = 0;
    for (int z = 0; z < 12; ++z)
        for (int y = 0; y < 12; ++y)
            for (int x = 0; x < 12; ++x) {
                const float r2 = float((x - 5) * (x - 5) + (y - 6) * (y - 6) + (z - 6) * (z - 6));
                const float value = 100.0f - std::sqrt(r2);
                v[static_cast<size_t>((z * 12 + y) * 12 + x)] = value;
                above += value > 96.5f;
            }
    write_bytes(s.dir / "ct.mha", mha({12, 12, 12}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(v)));
    const auto grid = read_image(s.dir / "ct.mha", {.threshold = 96.5});
    EXPECT_EQ(grid->getGridClass(), openvdb::GRID_FOG_VOLUME);
    EXPECT_EQ(static_cast<int64_t>(grid->activeVoxelCount()), above);
    EXPECT_TRUE(grid->tree().isValueOn(openvdb::Coord(5, 6, 6)));
    EXPECT_FALSE(grid->tree().isValueOn(openvdb::Coord(0, 0, 0)));
    for (auto it = grid->cbeginValueOn(); it; ++it) EXPECT_EQ(*it, 1.0f);
    EXPECT_TRUE(surface_facts(marching_cubes(*grid)).closed_manifold());

    try {
        read_image(s.dir / "ct.mha", {.threshold = 1000});
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("above the threshold 1000"), std::string::npos) << e.what();
    }
    EXPECT_THROW(read_image(s.dir / "ct.mha", {.threshold = std::nan("")}), InputError);

    // What init reads: many values, a histogram of all of them.
    const ImageValues values = image_values(s.dir / "ct.mha");
    EXPECT_TRUE(values.many);
    EXPECT_FALSE(values.integer);
    ASSERT_EQ(values.histogram.size(), 256u);
    EXPECT_EQ(std::accumulate(values.histogram.begin(), values.histogram.end(), int64_t{0}), 12 * 12 * 12);
    EXPECT_FLOAT_EQ(values.max, 100.0f);

    v[100] = std::numeric_limits<float>::infinity();
    write_bytes(s.dir / "inf.mha", mha({12, 12, 12}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(v)));
    EXPECT_THROW(read_image(s.dir / "inf.mha", {.threshold = 96.5}), InputError);
    // A NaN is neither above nor below a threshold: refused, not taken as outside.
    v[100] = std::nanf("");
    write_bytes(s.dir / "nan.mha", mha({12, 12, 12}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(v)));
    try {
        read_image(s.dir / "nan.mha", {.threshold = 96.5});
        ADD_FAILURE() << "a NaN voxel was read";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("has 1 NaN or infinite voxel values, the first at voxel (4, 8, 0)"),
                  std::string::npos)
            << e.what();
    }
}

TEST(ImageImporter, ImageValuesCountTheLabelsOfALabelMap)
{
    const Scratch s;
    std::vector<uint8_t> v(8 * 8 * 8, 0);
    for (size_t i = 0; i < 40; ++i) v[i] = 3;
    for (size_t i = 40; i < 45; ++i) v[i] = 7;
    write_bytes(s.dir / "labels.mha", mha({8, 8, 8}, {1, 1, 1}, {0, 0, 0}, "MET_UCHAR", raw(v)));
    const ImageValues values = image_values(s.dir / "labels.mha");
    EXPECT_FALSE(values.many);
    EXPECT_TRUE(values.integer);
    const std::vector<std::pair<double, int64_t>> expected = {{0, 512 - 45}, {3, 40}, {7, 5}};
    EXPECT_EQ(values.counts, expected);
    EXPECT_TRUE(values.histogram.empty());
}

TEST(ImageImporter, ReadsASingleVolume4DImageAndRefuses2DAndSeries)
{
    const Scratch s;
    Nifti n;
    n.datatype = 2;
    n.bitpix = 8;
    n.dim = {4, 4, 4, 4, 1, 1, 1, 1};
    n.data.assign(64, '\1');
    write_bytes(s.dir / "one.nii", n.bytes());
    EXPECT_EQ(read_image(s.dir / "one.nii")->activeVoxelCount(), 64u);

    n.dim = {4, 4, 4, 4, 2, 1, 1, 1};
    n.data.assign(128, '\1');
    write_bytes(s.dir / "two.nii", n.bytes());
    try {
        read_image(s.dir / "two.nii");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("more than one 3D volume"), std::string::npos) << e.what();
    }

    n.dim = {2, 4, 4, 1, 1, 1, 1, 1};
    n.data.assign(16, '\1');
    write_bytes(s.dir / "flat.nii", n.bytes());
    try {
        read_image(s.dir / "flat.nii");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("2D image"), std::string::npos) << e.what();
    }

    // NRRD keeps a trailing size 1 as a fourth axis.
    write_bytes(s.dir / "one.nrrd", nrrd("4 4 4 1", "", "uchar", std::string(64, '\1'), 4));
    EXPECT_EQ(read_image(s.dir / "one.nrrd")->activeVoxelCount(), 64u);
}

// The import's memory is bounded before any voxel is read: a compressed
// NIfTI whose header promises more voxels than the bound is refused without
// inflating it, and so is a MetaImage; a header that points its data at a
// device or a FIFO is refused rather than read without end or waited on.
TEST(ImageImporter, RefusesImagesBeyondTheMemoryBoundAndDataFilesThatAreNotFiles)
{
    const Scratch s;
    Nifti n;
    n.dim = {3, 64, 64, 64, 1, 1, 1, 1};
    n.data.assign(64 * 64 * 64, '\1');
    write_gz(s.dir / "ones.nii.gz", n.bytes());
    // 262,144 voxels of one byte and a float each: 1.25 MiB.
    try {
        read_image(s.dir / "ones.nii.gz", {.max_bytes = 1 << 20});
        FAIL() << "read beyond the bound";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("holds 262144 voxels of 1 bytes, which would take about 1.25 MiB to import, more "
                            "than the 1 MiB allowed"),
                  std::string::npos)
            << what;
        EXPECT_NE(what.find("Hint: crop the image"), std::string::npos) << what;
    }
    // Within the bound, the same file is read.
    EXPECT_EQ(read_image(s.dir / "ones.nii.gz", {.max_bytes = 2 << 20})->activeVoxelCount(), 64u * 64 * 64);
    write_bytes(s.dir / "big.mha", mha({64, 64, 64}, {1, 1, 1}, {0, 0, 0}, "MET_UCHAR", std::string(64 * 64 * 64, '\1')));
    EXPECT_THROW(read_image(s.dir / "big.mha", {.max_bytes = 1 << 20}), InputError);
    EXPECT_EQ(read_image(s.dir / "big.mha", {.max_bytes = 2 << 20})->activeVoxelCount(), 64u * 64 * 64);

    // A header whose voxels are /dev/zero (1260^3 of them), and one whose
    // voxels are a FIFO no one writes.
    write_bytes(s.dir / "device.mhd", "ObjectType = Image\nNDims = 3\nBinaryData = True\nDimSize = 1260 1260 1260\n"
                                      "ElementType = MET_UCHAR\nElementDataFile = /dev/zero\n");
    ASSERT_EQ(::mkfifo((s.dir / "voxels.raw").c_str(), 0600), 0);
    write_bytes(s.dir / "fifo.mhd", "ObjectType = Image\nNDims = 3\nBinaryData = True\nDimSize = 4 4 4\n"
                                    "ElementType = MET_UCHAR\nElementDataFile = voxels.raw\n");
    for (const char* name : {"device.mhd", "fifo.mhd"}) {
        try {
            read_image(s.dir / name);
            FAIL() << name << " was read";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("as its data file, which is not a regular file"), std::string::npos)
                << e.what();
        }
    }
}

TEST(ImageImporter, RefusesMalformedFiles)
{
    const Scratch s;
    EXPECT_THROW(read_image(s.dir / "missing.nii.gz"), IoError);
    write_bytes(s.dir / "picture.png", "not an image");
    try {
        read_image(s.dir / "picture.png");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(".nii.gz"), std::string::npos) << "lists the extensions: " << e.what();
    }

    // Truncated .nii.gz: cut in the header, in the data, and one byte short.
    const std::string whole = label_image().bytes();
    for (const size_t length : {size_t{0}, size_t{100}, size_t{348}, size_t{600}, whole.size() - 1}) {
        write_gz(s.dir / "cut.nii.gz", whole.substr(0, length));
        EXPECT_THROW(read_image(s.dir / "cut.nii.gz"), InputError) << "cut at " << length;
    }
    // ... and the compressed stream itself cut short.
    write_gz(s.dir / "whole.nii.gz", whole);
    const std::string gz = file_bytes(s.dir / "whole.nii.gz");
    write_bytes(s.dir / "cutgz.nii.gz", gz.substr(0, gz.size() / 2));
    EXPECT_THROW(read_image(s.dir / "cutgz.nii.gz"), InputError);

    // Wrong magic in each format.
    std::string bad = whole;
    std::memcpy(bad.data() + 344, "xyz\0", 4);
    write_bytes(s.dir / "magic.nii", bad);
    EXPECT_THROW(read_image(s.dir / "magic.nii"), InputError);
    write_bytes(s.dir / "magic.nrrd", "NRRX0004\n" + nrrd("2 2 2", "", "uchar", std::string(8, '\1')).substr(9));
    EXPECT_THROW(read_image(s.dir / "magic.nrrd"), InputError);
    write_bytes(s.dir / "magic.mha", "hello world\n");
    EXPECT_THROW(read_image(s.dir / "magic.mha"), InputError);

    // A compressed MetaImage cut short: the real level set at three lengths.
    const std::string vmtk = file_bytes(kLevelSet);
    for (const size_t length : {vmtk.size() / 2, vmtk.size() * 9 / 10, vmtk.size() - 100}) {
        write_bytes(s.dir / "cut.mha", vmtk.substr(0, length));
        EXPECT_THROW(read_image(s.dir / "cut.mha", {.level_set = true}), InputError) << "cut at " << length;
    }
    // Text voxels, whose end MetaIO does not check.
    write_bytes(s.dir / "text.mha", "ObjectType = Image\nNDims = 3\nBinaryData = False\nDimSize = 2 2 2\n"
                                    "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n1 1 1 1 1 1 1 1\n");
    EXPECT_THROW(read_image(s.dir / "text.mha"), InputError);

    // A header key longer than ITK's MetaIO field name, which its strcpy
    // overflows (found by fuzzing).
    write_bytes(s.dir / "key.mha", std::string(300, 'K') + " = 1\n" +
                                       mha({2, 2, 2}, {1, 1, 1}, {0, 0, 0}, "MET_UCHAR", std::string(8, '\1')));
    EXPECT_THROW(read_image(s.dir / "key.mha"), InputError);

    // Compressed MetaImage data that ITK's MetaIO would read past or inflate
    // forever (found by fuzzing, fuzz/regressions/metaimage): CompressedDataSize
    // missing, not a positive whole number, or larger than the data that
    // follow the header; and a zlib stream asking for a preset dictionary
    // (MET_PerformUncompression loops on inflate's Z_NEED_DICT).
    std::vector<float> ramp(6 * 6 * 6);
    for (size_t i = 0; i < ramp.size(); ++i) ramp[i] = static_cast<float>(i % 6) - 2.5f;
    const std::string zipped = compressed_mha({6, 6, 6}, "MET_FLOAT", raw(ramp));
    write_bytes(s.dir / "zipped.mha", zipped);
    EXPECT_NO_THROW(read_image(s.dir / "zipped.mha", {.level_set = true}));
    const size_t size_at = zipped.find("CompressedDataSize = ");
    const std::string size_line = zipped.substr(size_at, zipped.find('\n', size_at) + 1 - size_at);
    const size_t data_at = zipped.find("LOCAL\n") + 6;
    const std::string packed_size = std::to_string(zipped.size() - data_at);
    const auto expect_refused = [&](const std::string& name, const std::string& bytes, const std::string& mentions) {
        write_bytes(s.dir / name, bytes);
        try {
            read_image(s.dir / name);
            ADD_FAILURE() << name << " was read";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(mentions), std::string::npos) << name << ": " << e.what();
        }
    };
    std::string no_size = zipped;
    no_size.erase(size_at, size_line.size());
    expect_refused("no_size.mha", no_size, "no CompressedDataSize");
    for (const std::string bad : {"-5", "12abc", "0", "1e3"}) {
        std::string odd = zipped;
        odd.replace(size_at, size_line.size(), "CompressedDataSize = " + bad + "\n");
        expect_refused("odd_size.mha", odd, "CompressedDataSize = '" + bad + "'");
    }
    std::string large = zipped;
    large.replace(size_at, size_line.size(), "CompressedDataSize = 692\n");
    expect_refused("large_size.mha", large, "only " + packed_size + " bytes of data follow the header");
    std::string dictionary = zipped;
    dictionary[data_at] = 'x'; // 0x78 0x20: deflate, FDICT set, a multiple of 31
    dictionary[data_at + 1] = ' ';
    expect_refused("dictionary.mha", dictionary, "preset zlib dictionary");
    // MetaIO skips every '=', ':' and blank after a key: "CompressedData: =
    // True" is compressed to it, and must be to the checks too (found by
    // fuzzing, fuzz/regressions/metaimage: read as "= True" here, MetaIO's
    // inflate of the dictionary stream never ended).
    std::string separators = dictionary;
    const size_t flag_at = separators.find("CompressedData = True");
    ASSERT_NE(flag_at, std::string::npos);
    separators.replace(flag_at, 21, "CompressedData: = True");
    expect_refused("separators.mha", separators, "preset zlib dictionary");
    // MetaIO's key is a C string, ending at a NUL byte: "CompressedData",
    // NULs, then ": = True" is compressed to it too (found by fuzzing, as
    // above).
    std::string nuls = dictionary;
    nuls.replace(flag_at, 21, "CompressedData" + std::string(40, '\0') + ": = True");
    expect_refused("nuls.mha", nuls, "preset zlib dictionary");

    // Data in a pattern of slice files: MetaIO divides by the step, so a
    // missing or zero step was a division by zero (found by fuzzing). A
    // complete pattern is read.
    write_bytes(s.dir / "slice1.raw", std::string(4, '\1'));
    write_bytes(s.dir / "slice2.raw", std::string(4, '\1'));
    const std::string slices = "ObjectType = Image\nNDims = 3\nBinaryData = True\nDimSize = 2 2 2\n"
                               "ElementType = MET_UCHAR\nElementDataFile = slice%d.raw";
    write_bytes(s.dir / "slices.mhd", slices + " 1 2 1\n");
    EXPECT_NO_THROW(read_image(s.dir / "slices.mhd"));
    for (const std::string bad : {"", " 1 2", " 1 2 0", " 2 1 1", " 1 2 x"})
        expect_refused("pattern.mhd", slices + bad + "\n", "file pattern");

    // NDims sets how many numbers MetaIO reads for DimSize, Offset and the
    // NDims x NDims TransformMatrix, into a buffer of 4096: a huge or negative
    // NDims read for hours, one above 64 overflowed it (found by fuzzing).
    const std::string volume = mha({2, 2, 2}, {1, 1, 1}, {0, 0, 0}, "MET_UCHAR", std::string(8, '\1'));
    const size_t dims_at = volume.find("NDims = 3\n");
    ASSERT_NE(dims_at, std::string::npos);
    for (const std::string bad : {"22222222222222222222222222222223", "-3", "0", "65", "1e9"}) {
        std::string odd = volume;
        odd.replace(dims_at, 10, "NDims = " + bad + "\n");
        expect_refused("ndims.mha", odd, "NDims = '" + bad + "'");
    }
    // MetaIO takes the text after the next '=' as a key's value, across line
    // ends: a line without one, or with an empty value, swallowed the
    // ElementDataFile line below it and the voxels were read as header, where
    // a long key overflowed MetaIO's field name (found by fuzzing).
    const size_t type_at = volume.find("ElementType");
    for (const std::string bad : {"Junk\n", "Comment = \n", " = 1\n"}) {
        std::string odd = volume;
        odd.insert(type_at, bad);
        expect_refused("line.mha", odd, "that is not 'key = value'");
    }
    write_bytes(s.dir / "three.mha", volume);
    EXPECT_EQ(read_image(s.dir / "three.mha")->activeVoxelCount(), 8u);

    // Zero sizes.
    Nifti zero = label_image();
    zero.dim[3] = 0;
    write_bytes(s.dir / "zero.nii", zero.bytes());
    EXPECT_THROW(read_image(s.dir / "zero.nii"), InputError);
    write_bytes(s.dir / "zero.mha", mha({4, 0, 4}, {1, 1, 1}, {0, 0, 0}, "MET_UCHAR", ""));
    EXPECT_THROW(read_image(s.dir / "zero.mha"), InputError);
    write_bytes(s.dir / "zero.nrrd", nrrd("4 0 4", "", "uchar", ""));
    EXPECT_THROW(read_image(s.dir / "zero.nrrd"), InputError);

    // NaN in a level set; a level set with no inside.
    std::vector<float> field(6 * 6 * 6);
    for (size_t i = 0; i < field.size(); ++i) field[i] = static_cast<float>(i % 6) - 2.5f;
    write_bytes(s.dir / "ls.mha", mha({6, 6, 6}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(field)));
    EXPECT_NO_THROW(read_image(s.dir / "ls.mha", {.level_set = true}));
    field[77] = std::nanf("");
    write_bytes(s.dir / "nan.mha", mha({6, 6, 6}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(field)));
    try {
        read_image(s.dir / "nan.mha", {.level_set = true});
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("NaN"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("(5, 0, 2)"), std::string::npos) << "names the voxel: " << e.what();
    }
    std::fill(field.begin(), field.end(), 1.0f);
    write_bytes(s.dir / "outside.mha", mha({6, 6, 6}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(field)));
    EXPECT_THROW(read_image(s.dir / "outside.mha", {.level_set = true}), InputError);
    std::fill(field.begin(), field.end(), 0.0f);
    write_bytes(s.dir / "empty.mha", mha({6, 6, 6}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(field)));
    EXPECT_THROW(read_image(s.dir / "empty.mha"), InputError);

    // Data shorter than the header says.
    write_bytes(s.dir / "short.mha", mha({6, 6, 6}, {1, 1, 1}, {0, 0, 0}, "MET_FLOAT", raw(field).substr(0, 500)));
    EXPECT_THROW(read_image(s.dir / "short.mha"), InputError);
    write_bytes(s.dir / "short.nrrd", nrrd("6 6 6", "", "float", raw(field).substr(0, 500)));
    EXPECT_THROW(read_image(s.dir / "short.nrrd"), InputError);

    // Too many voxels: refused from the header, before any allocation.
    write_bytes(s.dir / "huge.nrrd", nrrd("2048 2048 1024", "", "uchar", ""));
    try {
        read_image(s.dir / "huge.nrrd");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("2^31"), std::string::npos) << e.what();
    }
    // Fewer voxels than 2^31 but more than a few bytes can hold, even
    // compressed: refused before the 16 GB buffer is allocated.
    for (const std::string encoding : {"raw", "gzip"}) {
        std::string big = nrrd("2048 2048 511", "", "double", std::string(40, '\1'));
        big.replace(big.find("encoding: raw"), 13, "encoding: " + encoding);
        write_bytes(s.dir / "big.nrrd", big);
        try {
            read_image(s.dir / "big.nrrd");
            FAIL() << encoding;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("even compressed"), std::string::npos) << e.what();
        }
    }
    write_bytes(s.dir / "big.mha", mha({2048, 2048, 511}, {1, 1, 1}, {0, 0, 0}, "MET_DOUBLE", std::string(40, '\1')));
    EXPECT_THROW(read_image(s.dir / "big.mha"), InputError);

    // Voxels too small for OpenVDB to invert the transform (found by fuzzing).
    Nifti tiny = label_image();
    tiny.pixdim = {1e-7f, 1e-7f, 1e-7f};
    write_bytes(s.dir / "tiny.nii", tiny.bytes());
    EXPECT_THROW(read_image(s.dir / "tiny.nii"), InputError);

    // A NaN in the sform, on which ITK's SVD aborts (found by fuzzing).
    Nifti nan_sform = label_image();
    set_sform(nan_sform, {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}, {1, 1, 1}, {0, 0, 0});
    nan_sform.srow[2][1] = std::nanf("");
    write_bytes(s.dir / "nan_sform.nii", nan_sform.bytes());
    EXPECT_THROW(read_image(s.dir / "nan_sform.nii"), InputError);

    // An sform offset of -1.7e38, on which ITK's SVD never returns (found by
    // fuzzing).
    Nifti far_sform = label_image();
    set_sform(far_sform, {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}, {1, 1, 1}, {0, 0, 0});
    far_sform.srow[0][3] = -1.7e38f;
    write_bytes(s.dir / "far_sform.nii", far_sform.bytes());
    try {
        read_image(s.dir / "far_sform.nii");
        ADD_FAILURE() << "an sform offset of -1.7e38 must be refused";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("beyond 1e9 in magnitude"), std::string::npos) << e.what();
    }

    // A sheared sform with no qform has no orthonormal direction.
    Nifti shear = label_image();
    set_sform(shear, {{{1, 0.5, 0}, {0, 1, 0}, {0, 0, 1}}}, {1, 1, 1}, {0, 0, 0});
    write_bytes(s.dir / "shear.nii", shear.bytes());
    EXPECT_THROW(read_image(s.dir / "shear.nii"), InputError);
}

// ---------------------------------------------------------------------------
// Corrupted variants: every one is read or refused with a scalemesh::Error.

struct FuzzTally {
    int read = 0, refused = 0;
};

void read_or_refuse(const fs::path& file, const ImageImportParams& params, FuzzTally& tally, const std::string& what)
{
    try {
        const auto grid = read_image(file, params);
        ASSERT_TRUE(grid);
        ++tally.read;
    } catch (const Error&) {
        ++tally.refused;
    } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": not a scalemesh::Error: " << e.what();
    } catch (...) {
        ADD_FAILURE() << what << ": unknown exception";
    }
}

// A copy cut at a random length, or with one to four random bytes replaced,
// half of them within the first `header` bytes, where parsers branch.
std::string corrupt(const std::string& bytes, size_t header, std::mt19937& rng)
{
    if (rng() % 3 == 0) return bytes.substr(0, rng() % bytes.size());
    std::string out = bytes;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) {
        const size_t at = (rng() % 2) ? rng() % std::min(header, out.size()) : rng() % out.size();
        out[at] = static_cast<char>(rng() % 256);
    }
    return out;
}

TEST(ImageImporter, RefusesCorruptedVariantsWithoutCrashing)
{
    const Scratch s;
    std::mt19937 rng(8);
    constexpr int kVariants = 300;

    std::vector<float> field(7 * 6 * 5);
    for (size_t i = 0; i < field.size(); ++i) field[i] = static_cast<float>(i % 7) - 3.0f;
    std::vector<int16_t> labels(7 * 6 * 5);
    for (size_t i = 0; i < labels.size(); ++i) labels[i] = static_cast<int16_t>(i % 3);

    const std::string nrrd_file =
        nrrd("7 6 5",
             "space: left-posterior-superior\nspace directions: (0.5,0,0) (0,0.7,0) (0,0,1.2)\n"
             "space origin: (1,2,3)\n",
             "short", raw(labels));
    const std::string mha_file = mha({7, 6, 5}, {0.5, 0.7, 1.2}, {1, 2, 3}, "MET_FLOAT", raw(field));
    const std::string zmha_file = compressed_mha({7, 6, 5}, "MET_FLOAT", raw(field));
    Nifti nifti = label_image();
    set_sform(nifti, rotation(0.3, false), {0.5, 0.7, 1.2}, {1, 2, 3});
    const std::string nifti_file = nifti.bytes();
    write_gz(s.dir / "base.nii.gz", nifti_file);
    const std::string nifti_gz = file_bytes(s.dir / "base.nii.gz");

    struct Case {
        std::string name;
        const std::string* bytes;
        size_t header;
        bool gzip_after; // corrupt the plain bytes, then compress
    };
    const std::vector<Case> cases{{"v.nrrd", &nrrd_file, nrrd_file.size() - raw(labels).size(), false},
                                  {"v.mha", &mha_file, mha_file.size() - raw(field).size(), false},
                                  {"z.mha", &zmha_file, zmha_file.find("LOCAL") + 6, false},
                                  {"v.nii", &nifti_file, 352, false},
                                  {"v.nii.gz", &nifti_file, 352, true},
                                  {"w.nii.gz", &nifti_gz, 20, false}};
    for (const Case& c : cases) {
        FuzzTally tally;
        const fs::path file = s.dir / c.name;
        for (int v = 0; v < kVariants; ++v) {
            const std::string bytes = corrupt(*c.bytes, c.header, rng);
            if (c.gzip_after) write_gz(file, bytes);
            else write_bytes(file, bytes);
            const std::string what = c.name + " variant " + std::to_string(v);
            read_or_refuse(file, {}, tally, what);
            read_or_refuse(file, {.level_set = true}, tally, what + " as a level set");
        }
        // Each kind of damage is seen: some variants survive (a flipped data
        // byte), and some are refused.
        EXPECT_GT(tally.read, 0) << c.name;
        EXPECT_GT(tally.refused, 0) << c.name;
        RecordProperty(c.name + "_read", tally.read);
        RecordProperty(c.name + "_refused", tally.refused);
    }
}

} // namespace
} // namespace scalemesh
