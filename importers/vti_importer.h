#pragma once
// VTK XML ImageData (.vti) voxels and their frame, for read_image
// (importers/image_importer.h), which turns them into a grid as it does the
// voxels ITK reads. Internal to importers/.

#include "importers/vtk_xml.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>

namespace scalemesh {

struct VtiVolume {
    std::array<int64_t, 3> size{};                     // voxels along each index axis
    std::array<double, 3> spacing{};                   // file units (mm for scalemesh)
    std::array<double, 3> origin{};                    // world position of voxel (0, 0, 0) of the grid
    std::array<std::array<double, 3>, 3> direction{}; // direction[world axis][index axis]
    vtk_xml::ScalarType type = vtk_xml::ScalarType::UInt8;
    std::unique_ptr<char[]> data; // size[0] * size[1] * size[2] values of `type`, x fastest, machine byte order
};

// Reads a .vti: WholeExtent, Origin, Spacing and Direction (9 numbers, row
// by row; identity when absent) of its <ImageData>, and its one Piece's
// point-data scalar array (the one the Scalars attribute names, else the
// first), of one component, in any encoding vtk_xml reads. An extent that
// does not start at 0 moves the origin to its first voxel: VTK's world
// position of index (i, j, k) is Origin + Direction * diag(Spacing) * (i, j, k)
// for i from the extent's start. Coordinates are taken as written (no LPS
// flip). Throws IoError when the file is missing or unreadable; InputError
// when it is not such an ImageData (the reason and what to do), with several
// pieces, an empty or inverted extent, more than 2^31 voxels, a spacing that
// is not positive and finite, a non-finite origin or direction, no point
// data (cell data only), several components, or damaged data.
VtiVolume read_vti_volume(const std::filesystem::path& path);

} // namespace scalemesh
