#pragma once
// Marching cubes over the active region of an OpenVDB grid (paper section 2,
// refs [15,19]): a closed, 2-manifold, consistently oriented surface with
// outward normals, in physical coordinates from the grid's transform.
//
// Ambiguous cube faces are resolved by a fixed rule that depends only on the
// face's four corners, so neighbouring cubes always agree: inside corners on
// a face diagonal are kept apart (inside is 6-connected, outside 26-connected,
// the default) or joined (inside 26-connected, outside 6-connected). The one
// interior ambiguity this leaves (two opposite corners of a cube on the
// 26-connected side) is resolved by a tunnel, so the surface bounds exactly
// the digital solid of that connectivity: its Euler characteristic is twice
// that of the voxel set.

#include "core/surface_mesh.h"

#include <openvdb/openvdb.h>

#include <optional>

namespace scalemesh {

enum class InsideConnectivity { Six, TwentySix };

struct IsosurfaceParams {
    // Iso value; default 0 for level sets (class GRID_LEVEL_SET: inside where
    // value < iso) and 0.5 for label and fog grids (inside where value > iso).
    std::optional<double> iso;
    InsideConnectivity connectivity = InsideConnectivity::Six;
};

// Throws InputError when the background is inside (the surface would not be
// bounded) or when no voxel is inside (no surface).
SurfaceMesh marching_cubes(const openvdb::FloatGrid& grid, const IsosurfaceParams& params = {});

// True when the grid is a signed distance field (inside negative).
bool is_level_set(const openvdb::GridBase& grid);

} // namespace scalemesh
