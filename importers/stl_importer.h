#pragma once
// Reading STL surfaces (binary or ASCII) into a SurfaceMesh.

#include "core/surface_mesh.h"

#include <cstdint>
#include <filesystem>

namespace scalemesh {

// Reads the triangles of a binary or ASCII STL (several solids in one ASCII
// file are merged). The file is binary when its size is 84 + 50 n for the
// count n in its header; otherwise it is ASCII if it begins with "solid" and
// contains "facet".
//
// Guarantees: vertices with exactly equal float32 coordinates are welded into
// one point (ASCII numbers are read as float32 too, so both variants of a file
// give the same mesh); points are numbered by first use; triangles keep the
// file's order and vertex order (the stored facet normals are ignored);
// triangles that weld to fewer than three distinct points are removed, and
// their number is stored in *degenerate_removed when given; every point is
// used by a triangle. Coordinates are multiplied by `scale` (file units to mm,
// e.g. 1000 for a file in metres). Closedness is not checked: callers use
// require_closed_manifold.
//
// Throws IoError when the file is missing or unreadable, and InputError when
// the file is empty, truncated or neither binary nor ASCII STL, holds no
// triangles (or only degenerate ones), has a NaN or infinite coordinate or an
// ASCII facet without exactly three vertices, or `scale` is not a positive
// finite number.
SurfaceMesh read_stl(const std::filesystem::path& path, double scale = 1.0, int64_t* degenerate_removed = nullptr);

} // namespace scalemesh
