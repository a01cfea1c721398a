#include "sizing/curvature.h"

#include "core/adjacency.h"
#include "core/errors.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

namespace scalemesh {

namespace {

constexpr int kTerms = 5; // z = a x^2 + b xy + c y^2 + d x + e y

// Solves the symmetric system A s = r by Gaussian elimination with partial
// pivoting; false when a pivot is negligible against the largest entry.
bool solve(std::array<std::array<double, kTerms>, kTerms>& A, std::array<double, kTerms>& r)
{
    double scale = 0;
    for (const auto& row : A)
        for (double v : row) scale = std::max(scale, std::abs(v));
    if (!(scale > 0)) return false;
    for (int c = 0; c < kTerms; ++c) {
        int pivot = c;
        for (int k = c + 1; k < kTerms; ++k)
            if (std::abs(A[k][c]) > std::abs(A[pivot][c])) pivot = k;
        if (std::abs(A[pivot][c]) <= 1e-12 * scale) return false;
        std::swap(A[c], A[pivot]);
        std::swap(r[c], r[pivot]);
        for (int k = c + 1; k < kTerms; ++k) {
            const double f = A[k][c] / A[c][c];
            for (int m = c; m < kTerms; ++m) A[k][m] -= f * A[c][m];
            r[k] -= f * r[c];
        }
    }
    for (int c = kTerms - 1; c >= 0; --c) {
        for (int m = c + 1; m < kTerms; ++m) r[c] -= A[c][m] * r[m];
        r[c] /= A[c][c];
    }
    return true;
}

// Two unit vectors completing n (unit) to a right-handed frame.
void tangent_frame(const Vec3& n, Vec3& u, Vec3& v)
{
    const Vec3 helper = std::abs(n.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    u = normalized(cross(helper, n));
    v = cross(n, u);
}

// The fit's points: the 1-ring, grown by the 2-ring when the 1-ring alone has
// fewer points than the fit has unknowns.
void stencil(const VertexTable& neighbours, int32_t i, std::vector<int32_t>& out)
{
    out.assign(neighbours.begin(i), neighbours.end(i));
    if (static_cast<int>(out.size()) >= kTerms) return;
    const size_t ring = out.size();
    for (size_t r = 0; r < ring; ++r)
        for (const int32_t* k = neighbours.begin(out[r]); k != neighbours.end(out[r]); ++k)
            if (*k != i && std::find(out.begin(), out.end(), *k) == out.end()) out.push_back(*k);
}

} // namespace

std::vector<double> curvature_radius(const SurfaceMesh& mesh, const std::vector<Vec3>& normals)
{
    if (normals.size() != mesh.points.size())
        throw InputError("curvature estimate got " + std::to_string(normals.size()) + " normals for " +
                             std::to_string(mesh.points.size()) + " points",
                         "pass the result of synthetic_normals for the same mesh");
    const double infinity = std::numeric_limits<double>::infinity();
    const VertexTable neighbours = vertex_neighbours(mesh);
    std::vector<double> radius(mesh.points.size(), infinity);
    std::vector<int32_t> points;

    for (int32_t i = 0; i < static_cast<int32_t>(mesh.points.size()); ++i) {
        if (norm2(normals[i]) == 0 || neighbours.size(i) == 0) continue;
        stencil(neighbours, i, points);
        if (static_cast<int>(points.size()) < kTerms) continue;
        Vec3 u, v;
        const Vec3 n = normalized(normals[i]);
        tangent_frame(n, u, v);

        // Coordinates in units of the mean neighbour distance keep the normal
        // equations well conditioned at any mesh scale.
        double h = 0;
        for (int32_t j : points) h += distance(mesh.points[j], mesh.points[i]);
        h /= static_cast<double>(points.size());
        if (!(h > 0)) continue;

        std::array<std::array<double, kTerms>, kTerms> A{};
        std::array<double, kTerms> r{};
        for (int32_t j : points) {
            const Vec3 q = (mesh.points[j] - mesh.points[i]) / h;
            const double x = dot(q, u), y = dot(q, v), z = dot(q, n);
            const std::array<double, kTerms> basis{x * x, x * y, y * y, x, y};
            for (int a = 0; a < kTerms; ++a) {
                for (int b = 0; b < kTerms; ++b) A[a][b] += basis[a] * basis[b];
                r[a] += basis[a] * z;
            }
        }
        if (!solve(A, r)) continue;

        // Back to mm: the quadratic coefficients scale with 1/h, the slopes
        // are dimensionless. Principal curvatures of the graph at the origin
        // from its first (E, F, G) and second (L, M, N) fundamental forms.
        const double a = r[0] / h, b = r[1] / h, c = r[2] / h, d = r[3], e = r[4];
        const double w = std::sqrt(1 + d * d + e * e);
        const double E = 1 + d * d, F = d * e, Gf = 1 + e * e;
        const double L = 2 * a / w, M = b / w, N = 2 * c / w;
        const double det = E * Gf - F * F;
        const double gauss = (L * N - M * M) / det;
        const double mean = (E * N - 2 * F * M + Gf * L) / (2 * det);
        const double kappa_max = std::abs(mean) + std::sqrt(std::max(0.0, mean * mean - gauss));
        if (kappa_max > 0) radius[i] = 1 / kappa_max;
    }
    return radius;
}

} // namespace scalemesh
