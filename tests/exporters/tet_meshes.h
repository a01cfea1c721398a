#pragma once
// Hand-made tet meshes for the exporter tests, built so their facts are known.

#include "core/tet_mesh.h"

#include <algorithm>
#include <map>

namespace scalemesh {

// A box of nx x ny x nz unit cubes (mm), each cut into six tets around its
// diagonal from corner 0 to corner 7 (the same diagonal everywhere, so the
// cuts conform), every tet positively oriented. Boundary faces are the faces
// of one tet, found by counting, oriented outwards; patch 1 is z = 0, patch 2
// is z = nz, patch 0 ("wall") the rest.
inline TetMesh box_of_cubes(int nx, int ny, int nz)
{
    TetMesh m;
    auto id = [&](int i, int j, int k) { return (k * (ny + 1) + j) * (nx + 1) + i; };
    for (int k = 0; k <= nz; ++k)
        for (int j = 0; j <= ny; ++j)
            for (int i = 0; i <= nx; ++i) m.points.push_back({double(i), double(j), double(k)});
    const int kuhn[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7}, {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                for (const auto& t : kuhn) {
                    Tet tet;
                    for (int c = 0; c < 4; ++c) tet[c] = id(i + (t[c] & 1), j + ((t[c] >> 1) & 1), k + ((t[c] >> 2) & 1));
                    if (tet_volume6(m.points[tet[0]], m.points[tet[1]], m.points[tet[2]], m.points[tet[3]]) < 0)
                        std::swap(tet[2], tet[3]);
                    m.tets.push_back(tet);
                }
    const int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    std::map<std::array<int32_t, 3>, std::pair<int, Triangle>> seen;
    for (const Tet& t : m.tets)
        for (const auto& f : faces) {
            const Triangle tri{t[f[0]], t[f[1]], t[f[2]]};
            std::array<int32_t, 3> key{tri[0], tri[1], tri[2]};
            std::sort(key.begin(), key.end());
            ++seen[key].first;
            seen[key].second = tri;
        }
    for (const auto& [key, entry] : seen) {
        if (entry.first != 1) continue;
        m.boundary_faces.push_back(entry.second);
        double z = 0;
        for (int32_t v : entry.second) z += m.points[v].z / 3.0;
        m.boundary_patch.push_back(z == 0.0 ? 1 : (z == double(nz) ? 2 : 0));
    }
    m.patch_names = {"wall", "inlet", "outlet"};
    return m;
}

// The unit cube in six tets, all of its boundary one "wall" patch.
inline TetMesh cube_in_six_tets()
{
    TetMesh m = box_of_cubes(1, 1, 1);
    m.boundary_patch.clear();
    m.patch_names.clear();
    return m;
}

} // namespace scalemesh
