#pragma once
// The core of a volume mesh with prism layers: the region above the layer
// stack (layer_stack.h), bounded by the stack's top triangles and the inner
// parts of the openings' caps, filled with tets that keep that boundary
// triangle for triangle. Gmsh's 3D Delaunay tetrahedrisation with its
// boundary recovery does the filling (its "initial mesh only": the recovery
// keeps a boundary whose triangles are all recovered, adding no point on
// it; the region's tets told from a cavity's here), then Gmsh's
// optimisation; a boundary with a cavity goes through Gmsh's full mesher,
// its refinement loop held to one try. The caller's cell passes follow with
// the boundary frozen.

#include "core/surface_mesh.h"
#include "core/tet_mesh.h"

#include <vector>

namespace scalemesh {

// Tets filling the region `boundary` encloses (closed, oriented outwards,
// no crossing triangles). On return, mesh.points starts with
// boundary.points unchanged (points Gmsh adds inside follow),
// mesh.boundary_faces == boundary.triangles, every tet is positively
// oriented and every boundary triangle is a face of exactly one tet.
// Throws StageError naming what Gmsh reported when it cannot mesh the
// region or changes its boundary. Gmsh runs in a child process of its own
// (core/child_process.h): a crash inside it is a StageError too, saying how
// the process ended.
//
// Runs in a GmshSession (gmsh_io/gmsh_session.h): one of its own, or
// inside an open one (the host's, adopted by mesh_gmsh_model), on a scratch
// model removed at the end, the caller's model current again and the
// options it set restored. One call at a time (Gmsh is not reentrant).
// `inside` are points to mesh with (embedded in the volume, after the
// boundary's in mesh.points, in their order); each must lie strictly inside
// the region. Gmsh's initial mesh adds no point of its own inside (its
// boundary recovery may add Steiner points, which would follow them).
TetMesh mesh_core(const SurfaceMesh& boundary, const std::vector<Vec3>& inside = {});

} // namespace scalemesh
