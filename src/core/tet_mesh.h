#pragma once
// TetMesh: the tetrahedral mesh handed from the volume stage to the exporters
// (DESIGN.md), as index arrays.

#include "core/surface_mesh.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace scalemesh {

using Tet = std::array<int32_t, 4>;

struct TetMesh {
    std::vector<Vec3> points;             // mm
    std::vector<Tet> tets;                // positively oriented: (b-a) . ((c-a) x (d-a)) > 0
    std::vector<Triangle> boundary_faces; // counter-clockwise seen from outside the mesh
    std::vector<int32_t> boundary_patch;  // patch id per boundary face; empty means all 0 (wall)
    std::vector<std::string> patch_names; // name per patch id; empty means {"wall"}
    std::vector<VertexField> point_fields; // per point, e.g. d, D
    std::vector<std::pair<std::string, std::vector<double>>> tet_fields; // per tet, e.g. aspect ratio, layer
};

// Six times the signed volume of tet (a, b, c, d).
double tet_volume6(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

struct TetMeshFacts {
    int64_t nonpositive_tets = 0;   // tets with volume <= 0
    double volume = 0;              // sum of tet volumes, mm^3
    double min_tet_volume = 0;
    int64_t boundary_faces = 0;     // faces with one tet
    int64_t overshared_faces = 0;   // faces with three or more tets
    bool boundary_matches = false;  // the one-tet faces are exactly boundary_faces, same orientation
};

// The faces of tet (a, b, c, d): face k leaves out corner k and is
// counter-clockwise seen from outside the tet.
inline constexpr int kTetFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

inline Triangle tet_face(const Tet& t, int k)
{
    return {t[kTetFaces[k][0]], t[kTetFaces[k][1]], t[kTetFaces[k][2]]};
}

// Which tet lies across each tet face, found by bucketing the faces by their
// smallest point id and sorting each bucket, so without a global sort.
struct TetFaceAdjacency {
    static constexpr int32_t kBoundary = -1;   // the face has one tet
    static constexpr int32_t kOvershared = -2; // three or more tets share it
    std::vector<int32_t> across;               // across[4 t + k]: the tet across face k of tet t
    int64_t overshared_faces = 0;              // distinct faces with three or more tets
};

// Throws std::out_of_range when a tet names a point the mesh does not have.
TetFaceAdjacency tet_face_adjacency(const TetMesh& mesh);

// Orders `tets` (points 0 .. point_count - 1) by their smallest point, a
// counting sort, then within each such group by their other points in
// increasing order: the order depends on the set of tets alone, not on the
// order they came in. Three of a tet's four faces have its smallest point as
// theirs, so matching faces by their smallest point (tet_face_adjacency, the
// exporters) then walks the tets in order. Each tet keeps its orientation.
void sort_tets_by_smallest_point(std::vector<Tet>& tets, size_t point_count);

// Checks the facts every exported mesh must have. Linear in the mesh size.
TetMeshFacts tet_mesh_facts(const TetMesh& mesh);
// The same with the adjacency of mesh.tets at hand (an exporter given the
// volume stage's). Throws std::invalid_argument when it has the wrong size.
TetMeshFacts tet_mesh_facts(const TetMesh& mesh, const TetFaceAdjacency& adjacency);

} // namespace scalemesh
