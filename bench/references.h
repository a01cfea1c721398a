#pragma once
// What the benchmarks share: the timing helpers, and the reference
// implementations each stage is measured against in the same run, on the
// same input (issue 9):
//   isosurface  OpenVDB tools::volumeToMesh
//   remeshing   CGAL Polygon_mesh_processing::isotropic_remeshing
//   volume      CGAL Delaunay_triangulation_3, plain insertion of the same points
//   pipeline    CGAL Mesh_3 make_mesh_3 on the same label image
// Each reference reports its own wall time without the conversion of our
// arrays into its types, so the ratios compare the algorithms.

#include "core/surface_mesh.h"
#include "core/vec3.h"

#include <openvdb/openvdb.h>

#include <chrono>
#include <cstddef>
#include <functional>
#include <vector>

namespace scalemesh::bench {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start);

// The median of `repeats` (at least one) wall times of `work`.
double median_seconds(int repeats, const std::function<void()>& work);

// The median of `repeats` (at least one) times that `timed_work` reports
// itself, for work whose set-up is not to be counted.
double median_of_reported(int repeats, const std::function<double()>& timed_work);

// The median of `values` (0 when empty).
double median(std::vector<double> values);

struct ReferenceRun {
    double seconds = 0; // the reference's own wall time, conversions excluded
    size_t items = 0;   // what it made: triangles, finite cells or tets
};

// OpenVDB volumeToMesh at iso value `iso`, adaptivity 0; items: triangles,
// a quad counting as two. Runs on the TBB threads the caller allows.
ReferenceRun openvdb_volume_to_mesh(const openvdb::FloatGrid& grid, double iso);

// CGAL isotropic_remeshing of `surface` (closed, oriented) at one target
// edge length (mm), `iterations` iterations, nothing protected; items:
// output triangles. `remeshed`, when given, receives the result.
ReferenceRun cgal_isotropic_remeshing(const SurfaceMesh& surface, double target_edge_mm, int iterations,
                                      SurfaceMesh* remeshed = nullptr);

// CGAL Delaunay_triangulation_3 built from `points` with the range
// constructor (CGAL sorts them spatially), sequential; items: finite cells.
ReferenceRun cgal_delaunay(const std::vector<Vec3>& points);

// Mesh_3's criteria (mm and degrees), the names of CGAL::Mesh_criteria_3.
struct Mesh3Criteria {
    double cell_size = 1.0;           // mm, upper bound on the circumradius of a tet
    double facet_size = 1.0;          // mm, upper bound on the surface Delaunay ball radius
    double facet_distance = 0.1;      // mm, upper bound on the surface approximation error
    double facet_angle = 25;          // degrees, lower bound on surface triangle angles
    double cell_radius_edge_ratio = 3;
};

// CGAL Mesh_3 make_mesh_3 (default perturbation and exudation, no Lloyd or
// ODT) on a Labeled_mesh_domain_3 of `labels` (a 0/1 grid as the phantoms
// give it), copied into a CGAL::Image_3 first (not timed). Sequential;
// items: tets in the complex.
ReferenceRun cgal_mesh_3(const openvdb::FloatGrid& labels, const Mesh3Criteria& criteria);

} // namespace scalemesh::bench
