#pragma once
// snappyHexMesh with addLayers on a closed surface written as STL: the
// OpenFOAM mesher a CFD engineer would otherwise use, run as the whole
// pipeline's second reference (issue 9). It runs OpenFOAM's `blockMesh` and
// `snappyHexMesh` (on the PATH, as the openfoam package installs them) as
// child processes in a case directory of its own and reads the cell count
// and the layer coverage from snappyHexMesh's log.

#include "core/surface_mesh.h"
#include "core/vec3.h"

#include <filesystem>
#include <string>

namespace scalemesh::bench {

struct SnappyParams {
    double cell_size = 1;  // edge of the background hex cells, surface units
    int layers = 3;        // nSurfaceLayers asked on the whole surface
    Vec3 inside;           // locationInMesh: a point inside the surface
};

struct SnappyRun {
    double seconds = 0;          // blockMesh and snappyHexMesh, wall time of both processes
    double snappy_seconds = 0;   // snappyHexMesh alone
    size_t cells = 0;            // the final mesh ("Layer mesh : cells:")
    double mean_layers = 0;      // the layer table's average layers on the surface patch
    double thickness_percent = 0; // its overall thickness as a percentage of the thickness asked
    std::string error;           // non-empty when a step failed; the log is then in the case directory
};

// Writes the case into `dir` (created; its contents replaced) and runs it.
SnappyRun snappy_hex_mesh(const SurfaceMesh& surface, const SnappyParams& params, const std::filesystem::path& dir);

} // namespace scalemesh::bench
