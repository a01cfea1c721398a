// Meshes an octahedron refined onto a sphere through the installed library and
// checks what the volume stage guarantees: positive tets whose volumes add up
// to the volume the boundary encloses, that volume equal to the input's, and
// fields of the right sizes; then writes its OpenFOAM case through the
// library. Exits 0 when all hold, 1 with a message if not.

#include <scalemesh/scalemesh.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <utility>

namespace {

using P = std::array<double, 3>;

double det(const P& a, const P& b, const P& c)
{
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

P at(const std::vector<double>& x, std::size_t i) { return {x[3 * i], x[3 * i + 1], x[3 * i + 2]}; }

double enclosed(const std::vector<double>& x, const std::vector<std::size_t>& tri)
{
    double v = 0;
    for (std::size_t f = 0; f < tri.size(); f += 3) v += det(at(x, tri[f]), at(x, tri[f + 1]), at(x, tri[f + 2])) / 6;
    return v;
}

scalemesh::SurfaceInput sphere(double r, int levels)
{
    std::vector<P> p = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    std::vector<std::array<std::size_t, 3>> f = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                                 {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    for (int level = 0; level < levels; ++level) {
        std::map<std::pair<std::size_t, std::size_t>, std::size_t> middle;
        const auto mid = [&](std::size_t a, std::size_t b) {
            const auto key = std::minmax(a, b);
            if (auto it = middle.find(key); it != middle.end()) return it->second;
            P m = {p[a][0] + p[b][0], p[a][1] + p[b][1], p[a][2] + p[b][2]};
            const double n = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
            p.push_back({m[0] / n, m[1] / n, m[2] / n});
            return middle[key] = p.size() - 1;
        };
        std::vector<std::array<std::size_t, 3>> next;
        for (const auto& [a, b, c] : f) {
            const std::size_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
            next.insert(next.end(), {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}});
        }
        f = std::move(next);
    }
    scalemesh::SurfaceInput s;
    for (const P& q : p) s.points.insert(s.points.end(), {r * q[0], r * q[1], r * q[2]});
    for (const auto& t : f) s.triangles.insert(s.triangles.end(), t.begin(), t.end());
    return s;
}

int fail(const char* what)
{
    std::fprintf(stderr, "consumer: %s\n", what);
    return 1;
}

} // namespace

int main()
{
    const scalemesh::SurfaceInput input = sphere(4.0, 4);
    scalemesh::MeshResult m;
    try {
        m = scalemesh::mesh_surface(input, {});
    } catch (const scalemesh::Error& e) {
        std::fprintf(stderr, "consumer: scalemesh error: %s\n", e.what());
        return 1;
    }
    const std::size_t n = m.point_count(), tets = m.tet_count();
    if (tets == 0) return fail("no tets");
    double volume = 0;
    for (std::size_t t = 0; t < tets; ++t) {
        const P a = at(m.points, m.tets[4 * t]);
        P e[3];
        for (int k = 0; k < 3; ++k) {
            const P b = at(m.points, m.tets[4 * t + k + 1]);
            e[k] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        }
        const double v = det(e[0], e[1], e[2]) / 6;
        if (!(v > 0)) return fail("a tet with volume <= 0");
        volume += v;
    }
    const double boundary = enclosed(m.points, m.boundary_triangles), original = enclosed(input.points, input.triangles);
    if (std::abs(volume - boundary) > 1e-9 * boundary) return fail("the tets do not fill the boundary");
    if (std::abs(boundary - original) > 1e-9 * original) return fail("the mesh does not keep the input's volume");
    if (m.d.size() != n || m.D.size() != n || m.D_out.size() != n || m.layers.size() != n)
        return fail("a per-point field of the wrong size");
    if (m.aspect_ratio.size() != tets || m.boundary_patch.size() != m.boundary_count())
        return fail("a per-tet or per-triangle array of the wrong size");
    bool bad_input_refused = false;
    try {
        scalemesh::SurfaceInput open = input;
        open.triangles.resize(open.triangles.size() - 3);
        scalemesh::mesh_surface(open, {});
    } catch (const scalemesh::InputError&) {
        bad_input_refused = true;
    }
    if (!bad_input_refused) return fail("a surface with a hole was not refused with InputError");
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "scalemesh-package-consumer-case";
    std::filesystem::remove_all(dir);
    try {
        const scalemesh::OpenFoamCase written = scalemesh::write_openfoam(m, dir);
        if (written.cells <= 0) return fail("write_openfoam wrote no cells");
    } catch (const scalemesh::Error& e) {
        std::fprintf(stderr, "consumer: write_openfoam: %s\n", e.what());
        return 1;
    }
    const bool polymesh = std::filesystem::is_regular_file(dir / "constant" / "polyMesh" / "owner") &&
                          std::filesystem::is_regular_file(dir / "report.json");
    std::filesystem::remove_all(dir);
    if (!polymesh) return fail("write_openfoam left no constant/polyMesh/owner or report.json");
    std::printf("consumer: %zu points, %zu tets, volume %.9g mm^3 (input %.9g mm^3)\n", n, tets, volume, original);
    return 0;
}
