#include "core/tet_mesh.h"

#include <algorithm>
#include <limits>

namespace scalemesh {

double tet_volume6(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    return dot(b - a, cross(c - a, d - a));
}

namespace {

// The faces of tet (a, b, c, d), each counter-clockwise seen from outside.
constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

struct Face {
    std::array<int32_t, 3> sorted;
    Triangle oriented;
    bool operator<(const Face& o) const { return sorted < o.sorted; }
};

Face make_face(const Triangle& t)
{
    Face f{{t[0], t[1], t[2]}, t};
    std::sort(f.sorted.begin(), f.sorted.end());
    return f;
}

// Rotates a triangle so that its smallest index comes first (same orientation).
Triangle canonical(Triangle t)
{
    while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
    return t;
}

} // namespace

TetMeshFacts tet_mesh_facts(const TetMesh& mesh)
{
    TetMeshFacts facts;
    facts.min_tet_volume = std::numeric_limits<double>::infinity();
    std::vector<Face> faces;
    faces.reserve(mesh.tets.size() * 4);
    for (const Tet& t : mesh.tets) {
        const double v = tet_volume6(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]) / 6.0;
        facts.volume += v;
        facts.min_tet_volume = std::min(facts.min_tet_volume, v);
        if (!(v > 0)) ++facts.nonpositive_tets;
        for (const auto& f : kFaces) faces.push_back(make_face({t[f[0]], t[f[1]], t[f[2]]}));
    }
    std::sort(faces.begin(), faces.end());
    std::vector<Triangle> boundary;
    for (size_t i = 0; i < faces.size();) {
        size_t j = i;
        while (j < faces.size() && faces[j].sorted == faces[i].sorted) ++j;
        if (j - i == 1) boundary.push_back(canonical(faces[i].oriented));
        else if (j - i > 2) ++facts.overshared_faces;
        i = j;
    }
    facts.boundary_faces = static_cast<int64_t>(boundary.size());
    std::vector<Triangle> expected;
    expected.reserve(mesh.boundary_faces.size());
    for (const Triangle& t : mesh.boundary_faces) expected.push_back(canonical(t));
    std::sort(boundary.begin(), boundary.end());
    std::sort(expected.begin(), expected.end());
    facts.boundary_matches = boundary == expected;
    return facts;
}

} // namespace scalemesh
