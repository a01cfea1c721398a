#pragma once
// Closed, outward-oriented test surfaces built analytically, shared by the
// smoothing and sizing tests. Every vertex lies exactly on the analytic shape.

#include "core/adjacency.h"
#include "core/surface_mesh.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <utility>

namespace scalemesh::test {

// Icosahedron subdivided `levels` times, vertices projected onto the sphere.
inline SurfaceMesh icosphere(double radius, int levels, Vec3 centre = {})
{
    const double t = (1 + std::sqrt(5.0)) / 2;
    std::vector<Vec3> p = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                           {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (Vec3& q : p) q = normalized(q);
    std::vector<Triangle> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                               {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                               {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int level = 0; level < levels; ++level) {
        std::map<std::pair<int32_t, int32_t>, int32_t> midpoint;
        auto mid = [&](int32_t a, int32_t b) {
            const auto key = std::minmax(a, b);
            auto [it, inserted] = midpoint.emplace(key, static_cast<int32_t>(p.size()));
            if (inserted) p.push_back(normalized(p[a] + p[b]));
            return it->second;
        };
        std::vector<Triangle> next;
        for (const Triangle& tri : f) {
            const int32_t ab = mid(tri[0], tri[1]), bc = mid(tri[1], tri[2]), ca = mid(tri[2], tri[0]);
            next.push_back({tri[0], ab, ca});
            next.push_back({tri[1], bc, ab});
            next.push_back({tri[2], ca, bc});
            next.push_back({ab, bc, ca});
        }
        f = std::move(next);
    }
    SurfaceMesh mesh;
    for (const Vec3& q : p) mesh.points.push_back(centre + radius * q);
    mesh.triangles = std::move(f);
    return mesh;
}

// Torus around the z axis: centre-line radius R, tube radius r, nu segments
// around the axis, nv around the tube. Vertex (i, j) is point i * nv + j at
// angles u = 2 pi i / nu, v = 2 pi j / nv; v = 0 is the outer equator.
inline SurfaceMesh uv_torus(double R, double r, int nu, int nv)
{
    SurfaceMesh mesh;
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            const double u = 2 * std::numbers::pi * i / nu, v = 2 * std::numbers::pi * j / nv;
            mesh.points.push_back({(R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
                                   r * std::sin(v)});
        }
    auto id = [&](int i, int j) { return static_cast<int32_t>(((i + nu) % nu) * nv + (j + nv) % nv); };
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            // d/du x d/dv points outward, so (i,j), (i+1,j), (i+1,j+1) is counter-clockwise from outside.
            mesh.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            mesh.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return mesh;
}

// Closed cylinder of radius r along z from z0 to z0 + length, centred on
// (cx, cy): n_around segments, n_along rings of wall quads, and flat caps as
// fans around a centre vertex. Wall vertex (ring k, angle i) is point
// k * n_around + i at angle 2 pi i / n_around; the two cap centres come last.
inline SurfaceMesh capped_cylinder(double r, double length, int n_around, int n_along, double cx = 0,
                                   double cy = 0, double z0 = 0)
{
    SurfaceMesh mesh;
    for (int k = 0; k <= n_along; ++k)
        for (int i = 0; i < n_around; ++i) {
            const double a = 2 * std::numbers::pi * i / n_around;
            mesh.points.push_back({cx + r * std::cos(a), cy + r * std::sin(a), z0 + length * k / n_along});
        }
    const auto bottom = static_cast<int32_t>(mesh.points.size());
    mesh.points.push_back({cx, cy, z0});
    const auto top = static_cast<int32_t>(mesh.points.size());
    mesh.points.push_back({cx, cy, z0 + length});
    auto id = [&](int k, int i) { return static_cast<int32_t>(k * n_around + (i + n_around) % n_around); };
    for (int k = 0; k < n_along; ++k)
        for (int i = 0; i < n_around; ++i) {
            mesh.triangles.push_back({id(k, i), id(k, i + 1), id(k + 1, i + 1)});
            mesh.triangles.push_back({id(k, i), id(k + 1, i + 1), id(k + 1, i)});
        }
    for (int i = 0; i < n_around; ++i) {
        mesh.triangles.push_back({bottom, id(0, i + 1), id(0, i)});
        mesh.triangles.push_back({top, id(n_along, i), id(n_along, i + 1)});
    }
    return mesh;
}

// Both surfaces as one mesh of two components.
inline SurfaceMesh merged(const SurfaceMesh& a, const SurfaceMesh& b)
{
    SurfaceMesh mesh = a;
    const auto offset = static_cast<int32_t>(a.points.size());
    mesh.points.insert(mesh.points.end(), b.points.begin(), b.points.end());
    for (Triangle t : b.triangles) mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    return mesh;
}

// Two parallel capped tubes of radius r along z whose walls are `gap` apart at
// x = -gap/2 (first tube, angle index 0) and x = +gap/2 (second tube, angle
// index n_around/2). n_around must be even.
inline SurfaceMesh parallel_tubes(double r, double gap, double length, int n_around, int n_along)
{
    return merged(capped_cylinder(r, length, n_around, n_along, -gap / 2 - r),
                  capped_cylinder(r, length, n_around, n_along, gap / 2 + r));
}

// Each point moved by a uniform random vector in the cube [-amplitude, amplitude]^3.
inline void add_noise(SurfaceMesh& mesh, double amplitude, unsigned seed = 12345)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-amplitude, amplitude);
    for (Vec3& p : mesh.points) {
        const double dx = u(rng), dy = u(rng), dz = u(rng);
        p += Vec3{dx, dy, dz};
    }
}

// Capped cylinder (r = 2, length 10, 32 around, 10 rings) whose top cap
// centre (returned in `vertex`) is moved within the cap plane to outside the
// rim. Its fan then lies exactly in the plane z = 10 with some triangles
// facing up and some facing down (normals exactly (0, 0, +1) and (0, 0, -1)),
// so no direction makes a positive dot product with all of them: the inward
// check of section 2.1 must fail there. Still closed and oriented
// combinatorially.
inline SurfaceMesh folded_cap_cylinder(int32_t& vertex)
{
    SurfaceMesh mesh = capped_cylinder(2.0, 10.0, 32, 10);
    vertex = static_cast<int32_t>(mesh.points.size()) - 1;
    mesh.points[vertex] = {3.0, 0.5, 10.0};
    return mesh;
}

inline double torus_distance(const Vec3& p, double R, double r)
{
    const double rho = std::hypot(p.x, p.y);
    return std::abs(std::hypot(rho - R, p.z) - r);
}

// A measured figure for RecordProperty, in a form that keeps small values.
inline std::string figure(double value)
{
    std::ostringstream out;
    out.precision(4);
    out << value;
    return out.str();
}

} // namespace scalemesh::test
