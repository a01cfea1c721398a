#pragma once
// Peak memory of a run, estimated before the heavy stages (sizing,
// remeshing, the volume mesh) so that a case too large for the machine stops
// with advice instead of being killed by the system. The volume stage and the
// export of its mesh dominate: measured on the sample cases and hostile
// inputs (docs/reliability.md), the peak resident memory is a base of about
// 95 MB (the libraries) plus about 250 bytes per marching cubes triangle and
// 1.8 to 2.4 kB per point of the volume mesh.

#include "core/memory_text.h"
#include "core/surface_mesh.h"
#include "sizing/feature_size.h"

#include <cstdint>
#include <optional>
#include <string>

namespace scalemesh {

struct MemoryModel {
    double base = 100e6;              // bytes: libraries, the process itself
    double per_surface_triangle = 250; // bytes per triangle of the smoothed surface (kept through the run)
    double per_volume_point = 2200;   // bytes per volume mesh point (triangulation, flips, export)
    double remeshed_edge_fraction = 0.6; // remeshing ends short of K/M d (docs/method.md): its edges
                                         // come out at about this fraction of it (0.5 to 0.7 measured)
};

// The machine's physical memory in bytes (sysconf).
int64_t physical_memory();

// Peak resident memory of this process so far, bytes (getrusage).
int64_t peak_resident_memory();

// The process's peak and current resident set (bytes) from
// /proc/self/status (VmHWM, VmRSS); nullopt where it cannot be read.
struct ResidentMemory {
    int64_t peak_bytes = 0;
    int64_t now_bytes = 0;
};
std::optional<ResidentMemory> resident_memory();

// Resets the process's peak resident set to its current one (Linux's
// /proc/self/clear_refs, "5"), so that the next resident_memory() peak is
// the peak since now. A process-wide effect (getrusage's peak is reset
// too): only for a run that owns its process. False where it cannot.
bool reset_peak_resident_memory();

// "8G", "512M", "1.5 GB", "300MiB", "2000000000": bytes (K, M, G, T are
// powers of 1024). Throws InputError naming `what` for anything else.
int64_t parse_memory_size(const std::string& text, const std::string& what);

// Points of the volume mesh Algorithm 4 makes, summed over the nodes of a
// sized surface: the node, up to floor(M/2) layer points d/M apart, then
// filler points every min(D, L_max)/M, all within D/2 of the node.
double volume_points(const FeatureSize& sizing, double M, double L_max);

// The same for the surface remeshing will make from `surface` (sized, not yet
// remeshed): each triangle holds area / (sqrt(3)/2 h^2) nodes of the edge
// length h = remeshed_edge_fraction K/M d, each with the points of its d and D.
double remeshed_volume_points(const SurfaceMesh& surface, const FeatureSize& sizing, double K, double M,
                              double L_max, const MemoryModel& model = {});

// Estimated peak bytes with `surface_triangles` smoothed surface triangles
// and `points` volume mesh points.
double estimate_peak_memory(int64_t surface_triangles, double points, const MemoryModel& model = {});

// Throws InputError when `estimate` exceeds `bound` (bytes): the estimate,
// what it comes from (`basis`) and what to change.
void require_memory(double estimate, int64_t bound, const std::string& basis);

} // namespace scalemesh
