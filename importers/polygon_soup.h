#pragma once
// What the surface readers share: a file's bytes, and turning the polygons a
// format stores into the welded, compact SurfaceMesh of read_surface
// (importers/surface_importer.h). Internal to importers/.

#include "core/surface_mesh.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

// Polygons as a file stores them: polygon k has the corners
// corners[offsets[k]] .. corners[offsets[k + 1] - 1], indices into points,
// unchecked. offsets starts with 0.
struct PolygonSoup {
    std::vector<Vec3> points;
    std::vector<int64_t> corners;
    std::vector<int64_t> offsets{0};
};

// The whole file. Throws IoError when it is missing, a directory or
// unreadable, and InputError when it is empty. Defined with the STL reader
// (stl_importer.cpp), which the surface_io library builds alone.
std::string read_file_bytes(const std::filesystem::path& path);

// Checks every coordinate is finite, every polygon has at least three corners
// and every index is in range (InputError naming the first offender and
// `path`), then fans polygons into triangles, welds exactly equal points,
// drops degenerate triangles, numbers points by first use and multiplies the
// coordinates by `scale`. Throws InputError when no triangle is left.
SurfaceMesh weld_polygons(const PolygonSoup& soup, double scale, const std::filesystem::path& path);

// The same, carrying one label per polygon (`polygon_labels`, aligned with
// soup's polygons; InputError when its length differs) to the triangles:
// `triangle_labels` receives one label per triangle of the result, in its
// order, each triangle keeping the label of the polygon it was fanned from.
// Defined with the STL reader (stl_importer.cpp).
SurfaceMesh weld_polygons(const PolygonSoup& soup, double scale, const std::filesystem::path& path,
                          const std::vector<int32_t>& polygon_labels, std::vector<int32_t>& triangle_labels);

// Throws InputError when `scale` is not a positive finite number.
void require_scale(double scale);

} // namespace scalemesh
