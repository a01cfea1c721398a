#pragma once
// Reading medical images (NIfTI, NRRD, MetaImage through ITK's ImageIO; VTK
// XML ImageData through importers/vti_importer.h) into the float grid the
// isosurface stage takes (paper section 2).

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace scalemesh {

// How voxel values become "inside". At most one of labels, threshold and
// level_set may be given; with none of them, every nonzero voxel is inside.
struct ImageImportParams {
    std::vector<int> labels{};          // label values merged into inside; empty: any nonzero voxel
    std::optional<double> threshold{};  // intensity images: inside where value > threshold (image units)
    bool level_set = false;             // signed field, negative inside: values kept as they are
    int64_t max_bytes = 0;              // memory the import may take (the run's --max-memory): an image whose
                                        // header promises more voxels than fit is refused before they are
                                        // read or inflated; 0: no bound
};

// Reads a 3D scalar image from .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd or
// .vti (the extension chooses the reader, case-insensitively).
//
// The grid's transform is the image-to-world map: image voxel (i,j,k) is grid
// voxel (i,j,k), at world = origin + Direction * diag(spacing) * (i,j,k).
// Coordinates are ITK's physical coordinates: LPS (x towards the patient's
// left, y posterior, z superior) in the file's length unit, millimetres for
// NIfTI (ITK converts its metres and microns to mm; it negates NIfTI's RAS x
// and y, so a NIfTI's world positions come out with x and y negated). NRRD
// and MetaImage origins, directions and spacings are taken as written, and
// so are a .vti's (VTK XML ImageData: Origin, Spacing, Direction row by row;
// no LPS flip; an extent starting at (i0, j0, k0) puts grid voxel (0,0,0) at
// VTK index (i0, j0, k0)). A .vti is read from its one piece's point-data
// scalars (the array its Scalars attribute names, else the first): ascii,
// inline binary or appended raw/base64 data, zlib-compressed or not, either
// byte order and header type, of any integer or floating-point type.
// The direction may be a reflection (determinant -1).
//
// Labels, threshold, or the default "nonzero": a 0/1 grid named "label" of
// class GRID_FOG_VOLUME, background 0, exactly the inside voxels active with
// value 1 (marching cubes' default iso 0.5 applies).
// level_set: a grid named "level_set" of class GRID_LEVEL_SET holding every
// image voxel, active, with its value; outside the image the background is
// positive (max |value| + the largest spacing), so the image border closes
// the surface. Values are not resampled or renormalised, so any iso value
// within the image's range can be used downstream (inside where value < iso).
//
// The grid carries the image size as Vec3i metadata "image_size" (voxels), so
// later stages can tell where the image border is.
//
// Integer labels are compared exactly up to 2^53; a NIfTI's scl_slope and
// scl_inter are applied before labels, threshold or level set. A 4D image is
// read when its fourth size is 1. Reads are serialised (ITK's NIfTI reader
// keeps static state); ITK's diagnostics are never printed but folded into
// the error message.
//
// Throws IoError when the file is missing or cannot be opened; InputError for
// an unsupported extension (listing the supported ones), a file ITK cannot
// parse (wrong magic, bad header: ITK's reason in one line), data shorter
// than the header promises, a 1D/2D image, a 4D image with more than one
// volume, a multi-component (vector, RGB, complex) image, a zero size, more
// than 2^31 voxels, more voxels than params.max_bytes holds (counted from the
// header, before any voxel is read or inflated), a data file named by the
// header that is not a regular file (a device or a FIFO), a non-positive or
// non-finite spacing, a singular
// direction matrix, NaN or infinite voxel values, NIfTI-2 (ITK 5.2 reads
// NIfTI-1 only), MetaImage voxels stored as text, a .vti that is not one piece
// of point data or whose stated sizes, offsets or compressed blocks do not
// match its bytes (vti_importer.h), conflicting params, or no voxel inside
// (listing up to 10 values present, or the value range).
openvdb::FloatGrid::Ptr read_image(const std::filesystem::path& path, const ImageImportParams& params = {});

// An image in memory: its voxels in one of the types the file readers take,
// on the grid the files describe, with an identity direction (the index axes
// are the world axes, as in a MetaImage without TransformMatrix).
enum class VoxelType { UInt8, Int8, UInt16, Int16, UInt32, Int32, UInt64, Int64, Float32, Float64 };

struct VoxelArray {
    const void* data = nullptr;           // voxel (0, 0, 0); not owned
    VoxelType type = VoxelType::UInt8;
    std::array<int64_t, 3> size{};        // voxels along index axes i, j, k
    std::array<int64_t, 3> strides{};     // elements from a voxel to its neighbour along i, j, k (may be negative)
    std::array<double, 3> spacing{};      // mm between voxel centres along i, j, k
    std::array<double, 3> origin{};       // mm: the centre of voxel (0, 0, 0)
};

// The grid read_image makes of a file holding these voxels (voxel (i, j, k)
// at origin + (i spacing[0], j spacing[1], k spacing[2])), with the same
// semantics of params and the same checks of the values. `name` stands for
// the file's path in messages. Throws InputError for a null pointer, a size
// below 1, more than 2^31 voxels or more than params.max_bytes, a
// non-positive or non-finite spacing, a non-finite origin, and as read_image
// for the values.
openvdb::FloatGrid::Ptr image_grid(const VoxelArray& voxels, const ImageImportParams& params,
                                   const std::string& name = "the image");

// What the voxels of an image hold, for choosing how to read it (scalemesh
// init): a label map has a few integer values, an intensity image many, a
// level set negative and positive ones.
struct ImageValues {
    static constexpr size_t kMost = 64;       // distinct values counted at most
    bool integer = false;                     // the voxel type is an integer type
    bool many = false;                        // more than kMost distinct values, or a non-integer value
    std::vector<std::pair<double, int64_t>> counts; // unless `many`: each value and its voxels, ascending
    double min = 0, max = 0;                  // of the finite values
    std::vector<int64_t> histogram;           // when `many`: voxels in each of 256 equal bins over [min, max]
};

// The values of the image at `path` (as read_image reads it, with the same
// checks of the file and of `max_bytes`; NaN values are not counted).
ImageValues image_values(const std::filesystem::path& path, int64_t max_bytes = 0);

// True when the extension is one read_image reads (.nii, .nii.gz, .nrrd,
// .nhdr, .mha, .mhd, .vti, any case).
bool is_image_file(const std::filesystem::path& path);

} // namespace scalemesh
