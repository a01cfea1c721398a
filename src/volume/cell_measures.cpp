// The measures of the cells a finite-volume solver objects to, as the cell
// passes (cell_passes.cpp) and OpenFOAM's checkMesh measure them.

#include "volume/improve.h"

#include "volume/quality.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace scalemesh {

namespace {

using improvement::face_cosine;
using improvement::parallel_marks;
using improvement::shared_face_cosine;

} // namespace

std::vector<char> tets_missing_floors(const TetMesh& mesh, double dihedral_floor, double ortho_bound)
{
    const auto& x = mesh.points;
    const auto at = [&](int32_t v) -> const Vec3& { return x[v]; };
    const double bound = std::cos(ortho_bound * M_PI / 180);
    const TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
    // A tet is marked for its own angle or for any of its interior faces,
    // each face measured from its lower tet as the passes measure it.
    return parallel_marks(0, mesh.tets.size(), [&](size_t i) {
        const Tet& t = mesh.tets[i];
        if (tet_min_dihedral_deg(x[t[0]], x[t[1]], x[t[2]], x[t[3]]) < dihedral_floor) return true;
        for (int k = 0; k < 4; ++k) {
            const int32_t u = adjacency.across[4 * i + k];
            if (u < 0) continue; // boundary or overshared
            const Tet& other = mesh.tets[u];
            const bool lower = u > static_cast<int32_t>(i);
            if (shared_face_cosine(at, lower ? t : other, lower ? other : t) < bound) return true;
        }
        return false;
    });
}

std::vector<int32_t> points_missing_floors(const TetMesh& mesh, int32_t surface_points, double dihedral_floor,
                                           double ortho_bound)
{
    const std::vector<char> marked = tets_missing_floors(mesh, dihedral_floor, ortho_bound);
    std::vector<int32_t> out;
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        if (marked[t])
            for (int32_t v : mesh.tets[t])
                if (v >= surface_points) out.push_back(v);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
}

double max_non_orthogonality_deg(const TetMesh& mesh, const TetFaceAdjacency& adjacency)
{
    const auto at = [&](int32_t v) -> const Vec3& { return mesh.points[v]; };
    const double worst = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, mesh.tets.size(), 1 << 13), 1.0,
        [&](const tbb::blocked_range<size_t>& range, double lowest) {
            for (size_t i = range.begin(); i != range.end(); ++i)
                for (int k = 0; k < 4; ++k) {
                    const int32_t u = adjacency.across[4 * i + k];
                    if (u > static_cast<int32_t>(i)) // each interior face once
                        lowest = std::min(lowest, face_cosine(at, mesh.tets[i], k, mesh.tets[u]));
                }
            return lowest;
        },
        [](double a, double b) { return std::min(a, b); });
    return std::acos(std::clamp(worst, -1.0, 1.0)) * 180 / M_PI;
}

} // namespace scalemesh
