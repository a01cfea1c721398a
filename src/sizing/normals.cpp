#include "sizing/normals.h"

#include "core/adjacency.h"
#include "core/errors.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

namespace scalemesh {

namespace {

constexpr double kPi = 3.14159265358979323846;

Vec3 triangle_normal(const SurfaceMesh& mesh, const Triangle& t)
{
    const Vec3& a = mesh.points[t[0]];
    return normalized(cross(mesh.points[t[1]] - a, mesh.points[t[2]] - a));
}

// The inward test of one vertex: its normal is nonzero and makes a strictly
// positive dot product with every nonzero triangle normal of its fan.
bool points_inward(const Vec3& normal, const Vec3* fan_normals, size_t count)
{
    if (!(norm2(normal) > 0)) return false;
    for (size_t i = 0; i < count; ++i)
        if (norm2(fan_normals[i]) != 0 && !(dot(normal, fan_normals[i]) > 0)) return false;
    return true;
}

} // namespace

std::vector<Vec3> synthetic_normals(const SurfaceMesh& mesh)
{
    return synthetic_normals(mesh, vertex_triangles(mesh));
}

// First each triangle, in parallel: its unit normal and its corner angles,
// two by atan2 and the third as what is left of pi (exact to rounding; a
// triangle whose normal vanishes adds nothing, so its angles are not
// needed). Then each vertex gathers over its fan, in parallel.
// vertex_triangles lists a fan in increasing triangle order, so a vertex adds
// its terms in the order a loop over the triangles would, and the sums are
// the same to the last bit whatever the thread count. A triangle with a
// repeated vertex is listed once per corner, so a repeat is skipped and its
// corners are taken together.
std::vector<Vec3> synthetic_normals(const SurfaceMesh& mesh, const VertexTable& fans, std::vector<char>* inward_ok)
{
    struct Shape {
        Vec3 normal;
        std::array<double, 3> angle;
    };
    std::vector<Shape> shape(mesh.triangles.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mesh.triangles.size(), 4096),
                      [&](const tbb::blocked_range<size_t>& range) {
                          for (size_t f = range.begin(); f != range.end(); ++f) {
                              const Triangle& t = mesh.triangles[f];
                              Shape& s = shape[f];
                              const Vec3& a = mesh.points[t[0]];
                              const Vec3& b = mesh.points[t[1]];
                              const Vec3& c = mesh.points[t[2]];
                              const Vec3 n = cross(b - a, c - a);
                              const double twice_area = norm(n);
                              if (!(twice_area > 0)) continue; // normal zero: adds nothing
                              s.normal = n / twice_area;
                              // Each corner's angle is atan2(|u x v|, u . v) of its two
                              // edges, accurate near 0 and pi where acos loses half the
                              // digits; |u x v| is twice the area at every corner.
                              s.angle[0] = std::atan2(twice_area, dot(b - a, c - a));
                              s.angle[1] = std::atan2(twice_area, dot(c - b, a - b));
                              s.angle[2] = std::max(0.0, kPi - s.angle[0] - s.angle[1]);
                          }
                      });

    std::vector<Vec3> normals(mesh.points.size());
    if (inward_ok) inward_ok->assign(mesh.points.size(), 0);
    tbb::parallel_for(tbb::blocked_range<int32_t>(0, static_cast<int32_t>(mesh.points.size()), 2048),
                      [&](const tbb::blocked_range<int32_t>& range) {
                          std::vector<Vec3> fan_normals;
                          for (int32_t v = range.begin(); v != range.end(); ++v) {
                              Vec3 sum;
                              fan_normals.clear();
                              for (const int32_t* f = fans.begin(v); f != fans.end(v); ++f) {
                                  if (f != fans.begin(v) && *f == f[-1]) continue;
                                  const Shape& s = shape[*f];
                                  fan_normals.push_back(s.normal);
                                  if (norm2(s.normal) == 0) continue;
                                  const Triangle& t = mesh.triangles[*f];
                                  for (int k = 0; k < 3; ++k)
                                      if (t[k] == v) sum += s.angle[k] * s.normal;
                              }
                              normals[v] = normalized(sum);
                              if (inward_ok)
                                  (*inward_ok)[v] = points_inward(normals[v], fan_normals.data(), fan_normals.size());
                          }
                      });
    return normals;
}

std::vector<char> inward_check(const SurfaceMesh& mesh, const std::vector<Vec3>& normals)
{
    return inward_check(mesh, vertex_triangles(mesh), normals);
}

std::vector<char> inward_check(const SurfaceMesh& mesh, const VertexTable& fans, const std::vector<Vec3>& normals)
{
    if (normals.size() != mesh.points.size())
        throw InputError("inward check got " + std::to_string(normals.size()) + " normals for " +
                             std::to_string(mesh.points.size()) + " points",
                         "pass the result of synthetic_normals for the same mesh");
    std::vector<char> ok(mesh.points.size(), 0);
    tbb::parallel_for(tbb::blocked_range<int32_t>(0, static_cast<int32_t>(mesh.points.size()), 2048),
                      [&](const tbb::blocked_range<int32_t>& range) {
                          std::vector<Vec3> fan_normals;
                          for (int32_t v = range.begin(); v != range.end(); ++v) {
                              fan_normals.clear();
                              for (const int32_t* f = fans.begin(v); f != fans.end(v); ++f)
                                  fan_normals.push_back(triangle_normal(mesh, mesh.triangles[*f]));
                              ok[v] = points_inward(normals[v], fan_normals.data(), fan_normals.size());
                          }
                      });
    return ok;
}

} // namespace scalemesh
