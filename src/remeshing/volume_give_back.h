#pragma once
// Private to src/remeshing (tests include it): giving back the volume that
// swaps, and merges into nodes that may not move, removed from a closed
// surface, by small moves along the nodes' area normals (the conserve_volume
// part of remesh_to_feature_size).

#include "remeshing/halfedge_mesh.h"

#include <vector>

namespace scalemesh::remeshing {

// `lost` holds, per vertex id, the volume (mm^3) removed at that node since
// the last call; a node may have lost volume (> 0) or gained it (< 0).
// Each node's amount is turned into an offset along its area normal N_v
// (the volume gradient is N_v / 3), averaged area-weighted over the closed
// 1-ring twice (over the 2-ring) so that no node carries a bump: the move
// of every node that is not `held` (per vertex id, nonzero: never moves).
// The moves are scaled
// by the factor that restores the volume to first order, kept in [0, 1],
// and one common offset of all free nodes along their unit normals takes up
// the rest; its slope (the free nodes' |N_v| / 3 summed) is positive
// whatever the signs in `lost`. (A factor alone is ill-conditioned: when
// gains and losses nearly balance its slope vanishes, and Newton's step on
// it threw nodes millions of mm away on a real STL.)
//
// Afterwards the enclosed volume is `volume` (mm^3) to round-off when any
// node is free, and `lost` is all zeros. Returns the largest move (mm).
double give_back_volume(HalfedgeMesh& mesh, std::vector<double>& lost, const std::vector<char>& held,
                        double volume);

// The enclosed volume (mm^3) of the live faces.
double enclosed_volume(const HalfedgeMesh& mesh);

} // namespace scalemesh::remeshing
