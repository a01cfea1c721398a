#pragma once
// Open-ended surfaces: the clipped vessels that VMTK, SimVascular, 3D Slicer
// and centreline tools write, whose ends are open boundary loops, and closed
// surfaces whose end caps carry face labels (SimVascular's ModelFaceID, a
// Gmsh physical surface).
//
// Each open end is closed for the stages that need a closed surface by a fan
// of triangles from its centre, and becomes an opening: a clip plane parallel
// to the loop's best-fit plane, just inside the loop's innermost point, that
// cut_and_cap (openings.h) cuts flat and caps like any other opening. The fan
// lies beyond the plane and is cut away with the last sliver of the wall.
//
//   boundary_loops      the open loops of a surface, or a clear refusal
//   close_open_ends     the loops closed, each with its plane and size
//   remove_label_caps   the planar labelled caps of a closed surface taken
//                       out, so that their loops become open ends
//   end_opening         the clip plane that cuts an end flat

#include "core/surface_mesh.h"
#include "openings/openings.h"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace scalemesh {

// The open boundary loops of `surface`, each as its vertices in the order the
// surface's triangles traverse its edges. Throws InputError, naming `what`,
// when the surface is not an oriented 2-manifold with boundary: non-manifold
// or inconsistently oriented edges, degenerate triangles, or a vertex where
// two loops touch. The message says how many loops there are and where, and
// what to do.
std::vector<std::vector<int32_t>> boundary_loops(const SurfaceMesh& surface, const std::string& what);

struct OpenEnd {
    std::vector<int32_t> loop; // its vertices, as boundary_loops gives them
    int32_t centre_point = -1; // the fan's centre, a point of the closed surface
    int32_t label = -1;        // the face label of the cap it replaces, -1 for a loop of the file
    Vec3 centre;               // perimeter centroid of the loop
    Vec3 normal;               // unit, out of the lumen (the closing fan's outward normal)
    double area = 0;           // mm^2, of the loop projected on its plane
    double radius = 0;         // mm, largest distance of a loop point from `centre`
    double deviation = 0;      // mm, largest distance of a loop point from the plane through `centre`
    double mean_edge = 0;      // mm, mean length of the loop's edges
};

struct ClosedEnds {
    SurfaceMesh surface;       // closed, oriented outwards (orient_outward applied)
    std::vector<OpenEnd> ends; // in order of decreasing area
    bool flipped = false;      // whether the file's triangles were wound inwards
};

// Closes every open loop of `surface` by a fan from the loop's perimeter
// centroid, orients the result outwards and measures each end. A loop of
// fewer than 6 edges is a hole, not an end: InputError saying where. `labels`
// (per loop, optional) is copied to OpenEnd::label. Throws as boundary_loops,
// and InputError when the closed surface is still not a closed 2-manifold
// (loops that cross themselves), naming the loop.
ClosedEnds close_open_ends(const SurfaceMesh& surface, const std::string& what,
                           const std::vector<int32_t>& labels = {});

// A face label's part of a closed surface, as remove_label_caps judges it.
struct LabelPart {
    int32_t label = 0;
    int64_t triangles = 0;
    double area = 0;          // mm^2
    double flatness = 0;      // largest distance of its points from their best-fit plane, over sqrt(area)
    double tolerance = 0;     // the flatness it was allowed: flat_tolerance, or its coordinates' single-precision
                              // rounding over sqrt(area) where that is larger
    int32_t pieces = 0;       // edge-connected pieces of its faces
    bool wall = false;        // the label of the largest area, never a cap
    bool cap = false;         // taken out as an end
};

// Why `part` is not a cap, in words ("not flat: its points leave its plane
// by up to 1.8e-06 of sqrt(area), beyond 1e-06"), or "" for a cap.
std::string why_not_a_cap(const LabelPart& part);

struct LabelCaps {
    SurfaceMesh surface;            // the surface without the cap faces (open where they were)
    std::vector<int32_t> loop_label; // per boundary loop of `surface` (boundary_loops order): the cap's label
    std::vector<LabelPart> parts;   // every label present, by increasing label
};

// Takes the labelled end caps out of a closed surface: a label is a cap when
// its faces lie on one plane (flatness below `flat_tolerance`, or below
// eight single-precision roundings of its largest coordinate over
// sqrt(area), so that caps read from float32 files such as STL and most VTP
// count as flat in any units), form one
// edge-connected piece, and it is not the label of the largest area (the
// wall). Everything else stays. The result is open where the caps were.
LabelCaps remove_label_caps(const SurfaceMesh& surface, const std::vector<int32_t>& labels,
                            double flat_tolerance = 1e-6);

// The clip plane that cuts `end` flat: parallel to the plane through its
// centre, (deviation + margin) inside it, with a radius that picks this end's
// crossing only.
OpeningSpec end_opening(const OpenEnd& end, const std::string& name, OpeningType type, double margin);

} // namespace scalemesh
