#include "sizing/normals.h"

#include "core/adjacency.h"
#include "core/errors.h"

#include <cmath>
#include <string>

namespace scalemesh {

namespace {

Vec3 triangle_normal(const SurfaceMesh& mesh, const Triangle& t)
{
    const Vec3& a = mesh.points[t[0]];
    return normalized(cross(mesh.points[t[1]] - a, mesh.points[t[2]] - a));
}

// atan2 of |cross| and dot stays accurate for angles near 0 and pi, where
// acos of the normalized dot product loses half the digits.
double angle_between(const Vec3& u, const Vec3& v)
{
    return std::atan2(norm(cross(u, v)), dot(u, v));
}

} // namespace

std::vector<Vec3> synthetic_normals(const SurfaceMesh& mesh)
{
    std::vector<Vec3> sum(mesh.points.size());
    for (const Triangle& t : mesh.triangles) {
        const Vec3 n = triangle_normal(mesh, t);
        if (norm2(n) == 0) continue;
        for (int k = 0; k < 3; ++k) {
            const Vec3& p = mesh.points[t[k]];
            const double theta = angle_between(mesh.points[t[(k + 1) % 3]] - p, mesh.points[t[(k + 2) % 3]] - p);
            sum[t[k]] += theta * n;
        }
    }
    for (Vec3& n : sum) n = normalized(n);
    return sum;
}

std::vector<char> inward_check(const SurfaceMesh& mesh, const std::vector<Vec3>& normals)
{
    if (normals.size() != mesh.points.size())
        throw InputError("inward check got " + std::to_string(normals.size()) + " normals for " +
                             std::to_string(mesh.points.size()) + " points",
                         "pass the result of synthetic_normals for the same mesh");
    std::vector<char> ok(mesh.points.size(), 0);
    for (size_t i = 0; i < normals.size(); ++i) ok[i] = norm2(normals[i]) > 0;
    for (const Triangle& t : mesh.triangles) {
        const Vec3 n = triangle_normal(mesh, t);
        if (norm2(n) == 0) continue;
        for (int32_t v : t)
            if (!(dot(normals[v], n) > 0)) ok[v] = 0;
    }
    return ok;
}

} // namespace scalemesh
