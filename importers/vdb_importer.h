#pragma once
// Reading OpenVDB files into the float grid the isosurface stage takes.

#include <openvdb/openvdb.h>

#include <filesystem>
#include <string>

namespace scalemesh {

struct VdbImportParams {
    std::string grid_name; // empty: the first float or integer grid in the file
};

// The named grid as a FloatGrid (integer and double grids converted, grid class,
// name and transform kept). Throws IoError when the file is missing or not a
// VDB, InputError when the grid is absent, not scalar, or has no active value.
openvdb::FloatGrid::Ptr read_vdb(const std::filesystem::path& path, const VdbImportParams& params = {});

// Writes one grid to `path` atomically (temporary name, then rename).
void write_vdb(const openvdb::GridBase& grid, const std::filesystem::path& path);

} // namespace scalemesh
