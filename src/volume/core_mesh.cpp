#include "volume/core_mesh.h"

#include "core/child_process.h"
#include "core/errors.h"
#include "gmsh_io/gmsh_session.h"

#include <gmsh.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <stdexcept>
#include <unordered_map>
#include <string>
#include <utility>
#include <vector>

namespace scalemesh {
namespace {

struct PointHash {
    size_t operator()(const Vec3& x) const
    {
        const std::hash<double> h;
        return h(x.x) ^ (h(x.y) * 0x9e3779b97f4a7c15ull) ^ (h(x.z) * 0xbf58476d1ce4e5b9ull);
    }
};

// Whether point x is inside the closed component `c` of `boundary` (by
// the parity of the triangles a ray from x along +z crosses).
bool encloses(const SurfaceMesh& boundary, const std::vector<int32_t>& component, int32_t c, const Vec3& x)
{
    bool in = false;
    for (size_t f = 0; f < boundary.triangles.size(); ++f) {
        if (component[f] != c) continue;
        const Triangle& t = boundary.triangles[f];
        const Vec3 &a = boundary.points[t[0]], &b = boundary.points[t[1]], &d = boundary.points[t[2]];
        // Where the vertical line through x meets the triangle's plane, if
        // inside the triangle's xy-projection (half-open edges).
        const double area = (b.x - a.x) * (d.y - a.y) - (d.x - a.x) * (b.y - a.y);
        if (area == 0) continue;
        const double u = ((b.x - x.x) * (d.y - x.y) - (d.x - x.x) * (b.y - x.y)) / area;
        const double v = ((d.x - x.x) * (a.y - x.y) - (a.x - x.x) * (d.y - x.y)) / area;
        const double w = 1 - u - v;
        if (u < 0 || v < 0 || w < 0 || u == 0 || v == 0) continue; // the half-open rule, roughly
        if (u * a.z + v * b.z + w * d.z > x.z) in = !in;
    }
    return in;
}

// Which of `tets` lie inside the region `boundary` encloses: the tets
// joined across faces that are not boundary triangles form components, and
// a component is inside when its tets' faces on the boundary wind as the
// boundary's triangles do (outward from the region), outside (a cavity's
// inside) when they wind the other way. A component whose faces on the
// boundary wind both ways has leaked through a boundary triangle the
// recovery did not keep: a StageError. One on no boundary triangle (none
// after a recovery that kept the boundary) is left out.
std::vector<char> enclosed_tets(const TetMesh& mesh, const TetFaceAdjacency& adjacency, size_t boundary_points)
{
    struct FaceHash {
        size_t operator()(const std::array<int32_t, 3>& f) const
        {
            return (size_t(uint32_t(f[0])) * 0x9e3779b97f4a7c15ull) ^ (size_t(uint32_t(f[1])) * 0xbf58476d1ce4e5b9ull) ^
                   size_t(uint32_t(f[2]));
        }
    };
    const auto sorted = [](std::array<int32_t, 3> f) {
        std::sort(f.begin(), f.end());
        return f;
    };
    std::unordered_map<std::array<int32_t, 3>, Triangle, FaceHash> wall;
    wall.reserve(mesh.boundary_faces.size());
    for (const Triangle& t : mesh.boundary_faces) wall.emplace(sorted({t[0], t[1], t[2]}), t);
    const auto same_winding = [](const Triangle& a, const std::array<int32_t, 3>& b) {
        for (int r = 0; r < 3; ++r)
            if (a[0] == b[r] && a[1] == b[(r + 1) % 3] && a[2] == b[(r + 2) % 3]) return true;
        return false;
    };
    const size_t count = mesh.tets.size();
    std::vector<int32_t> component(count, -1);
    std::vector<std::array<int64_t, 2>> votes; // per component: boundary faces wound with the boundary, against
    std::vector<size_t> stack;
    for (size_t seed = 0; seed < count; ++seed) {
        if (component[seed] >= 0) continue;
        const int32_t c = static_cast<int32_t>(votes.size());
        votes.push_back({0, 0});
        component[seed] = c;
        stack.push_back(seed);
        while (!stack.empty()) {
            const size_t t = stack.back();
            stack.pop_back();
            for (int k = 0; k < 4; ++k) {
                const std::array<int32_t, 3> face{mesh.tets[t][kTetFaces[k][0]], mesh.tets[t][kTetFaces[k][1]],
                                                  mesh.tets[t][kTetFaces[k][2]]};
                bool on_boundary = false;
                if (face[0] < int32_t(boundary_points) && face[1] < int32_t(boundary_points) &&
                    face[2] < int32_t(boundary_points))
                    if (const auto it = wall.find(sorted(face)); it != wall.end()) {
                        on_boundary = true;
                        ++votes[c][same_winding(it->second, face) ? 0 : 1];
                    }
                const int32_t across = adjacency.across[4 * t + k];
                if (on_boundary || across < 0 || component[across] >= 0) continue;
                component[across] = c;
                stack.push_back(static_cast<size_t>(across));
            }
        }
    }
    for (const auto& [with, against] : votes)
        if (with > 0 && against > 0)
            throw StageError("volume", "Gmsh's core lost a triangle of the prism layers' top: a region of its tets "
                                       "has " + std::to_string(with) + " faces on the top wound as the top and " +
                                       std::to_string(against) + " wound against it");
    std::vector<char> keep(count);
    for (size_t t = 0; t < count; ++t) keep[t] = votes[component[t]][0] > 0;
    return keep;
}

// Keeps the tets `keep` marks, in order, and their adjacency with them: a
// face across to a tet left out becomes a boundary face. Leaving tets out
// makes no face overshared, so only a mesh that had one is matched afresh.
void keep_tets(TetMesh& mesh, TetFaceAdjacency& adjacency, const std::vector<char>& keep)
{
    std::vector<int32_t> index(mesh.tets.size(), TetFaceAdjacency::kBoundary);
    size_t kept = 0;
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        if (keep[t]) index[t] = static_cast<int32_t>(kept++);
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        if (!keep[t]) continue;
        const size_t to = static_cast<size_t>(index[t]);
        mesh.tets[to] = mesh.tets[t];
        for (int k = 0; k < 4; ++k) {
            const int32_t across = adjacency.across[4 * t + k];
            adjacency.across[4 * to + k] = across >= 0 ? index[across] : across;
        }
    }
    mesh.tets.resize(kept);
    adjacency.across.resize(4 * kept);
    if (adjacency.overshared_faces != 0) adjacency = tet_face_adjacency(mesh);
}

std::string last_error()
{
    std::string error;
    try {
        gmsh::logger::getLastError(error);
    } catch (...) {
    }
    return error;
}

// What Gmsh made of the core: the points it meshed with beyond the
// boundary's (the embedded ones first, in their order, then those it added),
// its tets over the boundary's points and these, and the last error it
// logged (empty when none).
struct GmshCore {
    std::vector<Vec3> points;
    std::vector<Tet> tets;
    std::string last_error;
};

template <class T>
void append_array(std::string& bytes, const std::vector<T>& values)
{
    const uint64_t count = values.size();
    bytes.append(reinterpret_cast<const char*>(&count), sizeof count);
    if (count > 0) bytes.append(reinterpret_cast<const char*>(values.data()), count * sizeof(T));
}

template <class T>
std::vector<T> read_array(const std::string& bytes, size_t& at)
{
    uint64_t count = 0;
    if (bytes.size() - at < sizeof count) throw StageError("volume", "the core's process answered short");
    std::memcpy(&count, bytes.data() + at, sizeof count);
    at += sizeof count;
    if ((bytes.size() - at) / sizeof(T) < count) throw StageError("volume", "the core's process answered short");
    std::vector<T> values(count);
    if (count > 0) std::memcpy(values.data(), bytes.data() + at, count * sizeof(T));
    at += count * sizeof(T);
    return values;
}

std::string encode(const GmshCore& core)
{
    std::string bytes;
    append_array(bytes, core.points);
    append_array(bytes, core.tets);
    append_array(bytes, std::vector<char>(core.last_error.begin(), core.last_error.end()));
    return bytes;
}

GmshCore decode(const std::string& bytes)
{
    size_t at = 0;
    GmshCore core;
    core.points = read_array<Vec3>(bytes, at);
    core.tets = read_array<Tet>(bytes, at);
    const std::vector<char> error = read_array<char>(bytes, at);
    core.last_error.assign(error.begin(), error.end());
    if (at != bytes.size()) throw StageError("volume", "the core's process answered more than a core");
    return core;
}

// A fault of Gmsh's core found here, its message whole.
struct CoreError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// Gmsh's tets for the region `boundary` encloses, with the points `inside`
// embedded: the work of mesh_core's child process, which sets the session's
// options and makes its scratch model there (in `session`, the parent's:
// a GmshSession opened here would wait on the parent's lock, held by no
// thread of the child's). Throws std::runtime_error (a CoreError, or what
// Gmsh reported).
GmshCore gmsh_core(GmshSession& session, const SurfaceMesh& boundary, const std::vector<Vec3>& inside)
{
    const size_t nb = boundary.points.size();
    // An error Gmsh meets throws (caught below, and named) instead of ending
    // the process, whatever a host's session had set.
    session.set_option("General.AbortOnError", 3);
    // Gmsh's optimisation (edge swaps for the tets' shape) runs after the
    // mesh, at a quality threshold of 0.3: the cell passes that follow mend
    // dihedral angles and non-orthogonality, not the interpolation weights
    // and volume ratios that checkMesh -allGeometry judges, which without it
    // failed on 5 of the 15 sample cases. Gmsh's refinement loop, which
    // inserts no point in a volume bounded by a discrete surface without a
    // size field, is held to one try (it tried the circumcentre of every
    // tet whose circumradius exceeds its shortest edge and rejected each:
    // 642,970 tries, 35 of a 46 s volume stage on the 256 torus box).
    session.set_option("Mesh.Optimize", 1);
    session.set_option("Mesh.OptimizeThreshold", 0.3);
    session.set_option("Mesh.MaxIterDelaunay3D", 1);
    // Every option that shapes the tets set here, whatever a host's session
    // set for its own model: the same core from the command line and
    // inside a host. The core's tets join the boundary's points and the
    // fillers given (the paper's spacing, min(D, L_max) / M), as the
    // conditional Delaunay insertion of the paper's layers does; the
    // initial mesh adds no point of its own but the Steiner points its
    // boundary recovery may need (none on the 256 torus box). The size
    // options matter only to a refinement, which the initial mesh does not
    // run: once Gmsh's refinement, sized from the boundary, had refined the
    // core down to the layers' top triangles (on the 256 torus box 2.8
    // times the tets of the Delaunay layers, 92.8 of the 98.5 s of the
    // volume stage).
    session.set_option("Mesh.MeshSizeMax", 1e22);
    session.set_option("Mesh.MeshSizeMin", 0);
    session.set_option("Mesh.MeshSizeFactor", 1);
    session.set_option("Mesh.MeshSizeFromPoints", 0);
    session.set_option("Mesh.MeshSizeFromCurvature", 0);
    session.set_option("Mesh.MeshSizeExtendFromBoundary", 0);
    session.set_option("Mesh.OptimizeNetgen", 0);
    session.set_option("Mesh.ElementOrder", 1);
    session.set_option("Mesh.Smoothing", 1);
    session.set_option("Mesh.RandomFactor3D", 1e-12);
    session.set_option("Mesh.QualityType", 2);
    session.set_option("Mesh.RandomSeed", 1);
    // One thread: OpenMP's threads do not survive the fork once a host ran
    // them (a host that meshed with several threads before would leave the
    // child waiting for them for ever).
    session.set_option("General.NumThreads", 1);
    session.set_option("Mesh.MaxNumThreads1D", 1);
    session.set_option("Mesh.MaxNumThreads2D", 1);
    session.set_option("Mesh.MaxNumThreads3D", 1);
    const ScratchModel model("scalemesh_core");

    TetMesh mesh;
    mesh.points = boundary.points;
    try {
        gmsh::logger::start();
        // One discrete surface per component of the boundary, all sharing
        // the node tags 1..nb; a component enclosing positive volume bounds
        // a region of its own, one enclosing negative volume is a cavity of
        // the smallest such region around it.
        int32_t count = 0;
        const std::vector<int32_t> component = triangle_components(boundary, &count);
        std::vector<std::vector<size_t>> nodes(count);
        std::vector<double> volume6(count, 0.0);
        std::vector<Vec3> corner(count);
        for (size_t f = 0; f < boundary.triangles.size(); ++f) {
            const Triangle& t = boundary.triangles[f];
            const int32_t c = component[f];
            for (int32_t v : t) nodes[c].push_back(static_cast<size_t>(v) + 1);
            volume6[c] += dot(boundary.points[t[0]], cross(boundary.points[t[1]], boundary.points[t[2]]));
            corner[c] = boundary.points[t[0]];
        }
        std::vector<size_t> node_tags(nb);
        std::vector<double> coords(3 * nb);
        for (size_t i = 0; i < nb; ++i) {
            node_tags[i] = i + 1;
            coords[3 * i] = boundary.points[i].x;
            coords[3 * i + 1] = boundary.points[i].y;
            coords[3 * i + 2] = boundary.points[i].z;
        }
        std::vector<int> surfaces(count);
        for (int32_t c = 0; c < count; ++c) {
            surfaces[c] = gmsh::model::addDiscreteEntity(2);
            if (c == 0) gmsh::model::mesh::addNodes(2, surfaces[c], node_tags, coords);
            gmsh::model::mesh::addElementsByType(surfaces[c], 2, {}, nodes[c]);
        }
        std::vector<int> volumes;
        std::vector<std::vector<int>> loops(count);
        for (int32_t c = 0; c < count; ++c)
            if (volume6[c] > 0) loops[c].push_back(gmsh::model::geo::addSurfaceLoop({surfaces[c]}));
        for (int32_t c = 0; c < count; ++c) {
            if (volume6[c] > 0) continue;
            int32_t around = -1; // the smallest region whose outer surface contains this cavity
            for (int32_t o = 0; o < count; ++o)
                if (volume6[o] > 0 && encloses(boundary, component, o, corner[c]) &&
                    (around < 0 || volume6[o] < volume6[around]))
                    around = o;
            if (around < 0) throw CoreError("the core's boundary has a cavity outside every region");
            loops[around].push_back(gmsh::model::geo::addSurfaceLoop({surfaces[c]}));
        }
        for (int32_t c = 0; c < count; ++c)
            if (volume6[c] > 0) volumes.push_back(gmsh::model::geo::addVolume(loops[c]));
        std::vector<int> embedded;
        embedded.reserve(inside.size());
        for (const Vec3& x : inside) embedded.push_back(gmsh::model::geo::addPoint(x.x, x.y, x.z, 0.0));
        gmsh::model::geo::synchronize();
        // Each point in the region that contains it.
        if (!embedded.empty()) {
            std::vector<std::vector<int>> in(volumes.size());
            for (size_t k = 0; k < inside.size(); ++k) {
                size_t r = 0;
                for (int32_t c = 0, region = 0; c < count && volumes.size() > 1; ++c) {
                    if (!(volume6[c] > 0)) continue;
                    if (encloses(boundary, component, c, inside[k])) r = region;
                    ++region;
                }
                in[r].push_back(embedded[k]);
            }
            for (size_t r = 0; r < volumes.size(); ++r)
                if (!in[r].empty()) gmsh::model::mesh::embed(0, in[r], 3, volumes[r]);
        }
        // Without a cavity, Gmsh's initial mesh alone (the recovery's tets,
        // which enclosed_tets classifies below) and then its optimisation:
        // its full mesher would classify the tets through two sorted sets of
        // their faces (4 s on the 256 torus box). With a cavity, the full
        // mesher, whose classification leaves the cavity's inside out before
        // the optimisation swaps edges (a swap across a cavity's surface
        // with the cavity's tets still there would cut the surface).
        const bool cavity = std::any_of(volume6.begin(), volume6.end(), [](double v) { return !(v > 0); });
        session.set_option("Mesh.Algorithm3D", cavity ? 1 : 3);
        gmsh::model::mesh::generate(3);
        if (!cavity) gmsh::model::mesh::optimize("");

        // Gmsh numbers the nodes its own way: each is known by where it is,
        // the boundary's and the embedded ones (which it does not move), and
        // any other is a point it added.
        std::unordered_map<Vec3, int32_t, PointHash> id_of;
        for (size_t i = 0; i < mesh.points.size(); ++i) id_of.emplace(mesh.points[i], static_cast<int32_t>(i));
        for (const Vec3& x : inside) {
            id_of.emplace(x, static_cast<int32_t>(mesh.points.size()));
            mesh.points.push_back(x);
        }
        std::vector<size_t> tags;
        std::vector<double> xyz, parametric;
        gmsh::model::mesh::getNodes(tags, xyz, parametric, -1, -1, false, false);
        std::unordered_map<size_t, int32_t> id_of_tag;
        for (size_t k = 0; k < tags.size(); ++k) {
            const Vec3 x{xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]};
            const auto [it, added] = id_of.emplace(x, static_cast<int32_t>(mesh.points.size()));
            if (added) mesh.points.push_back(x);
            id_of_tag[tags[k]] = it->second;
        }
        std::vector<size_t> elements, corners;
        gmsh::model::mesh::getElementsByType(4, elements, corners);
        mesh.tets.reserve(elements.size());
        for (size_t e = 0; e < elements.size(); ++e) {
            Tet tet;
            for (int k = 0; k < 4; ++k) {
                const auto it = id_of_tag.find(corners[4 * e + k]);
                if (it == id_of_tag.end()) throw CoreError("Gmsh's core has a tet on an unknown node");
                tet[k] = it->second;
            }
            const Vec3 &a = mesh.points[tet[0]], &b = mesh.points[tet[1]], &c = mesh.points[tet[2]],
                       &d = mesh.points[tet[3]];
            if (tet_volume6(a, b, c, d) < 0) std::swap(tet[2], tet[3]);
            mesh.tets.push_back(tet);
        }
        gmsh::logger::stop();
    } catch (const std::string& message) {
        throw std::runtime_error("Gmsh could not mesh the core inside the prism layers: " + message);
    } catch (const CoreError&) {
        throw;
    } catch (...) {
        throw std::runtime_error("Gmsh could not mesh the core inside the prism layers: " + last_error());
    }
    GmshCore core;
    core.points.assign(mesh.points.begin() + static_cast<std::ptrdiff_t>(nb), mesh.points.end());
    core.tets = std::move(mesh.tets);
    core.last_error = last_error();
    return core;
}

} // namespace

TetMesh mesh_core(const SurfaceMesh& boundary, const std::vector<Vec3>& inside)
{
    const size_t nb = boundary.points.size();
    // Gmsh works in a child process: a crash inside it (its boundary
    // recovery has ended in a segmentation fault, in TetGen's flip31 on
    // Gmsh 4.8) is then a StageError, after which the pipeline builds the
    // paper's layers, not the end of the run. The session is opened here,
    // so that a host's is adopted and Gmsh is held for the call; what the
    // child does to Gmsh's state stays in the child.
    GmshSession session;
    GmshCore core;
    try {
        core = decode(run_in_child_process([&] { return encode(gmsh_core(session, boundary, inside)); }));
    } catch (const ChildProcessError& e) {
        if (e.threw()) throw StageError("volume", e.what());
        // Interrupted from outside: the run stops, it does not try the
        // paper's layers instead.
        if (e.interrupted()) throw Error(std::string("volume: the process meshing the core ") + e.what());
        throw StageError("volume", std::string("Gmsh failed meshing the core inside the prism layers: its process ") +
                                       e.what());
    }
    TetMesh mesh;
    mesh.points = boundary.points;
    mesh.points.insert(mesh.points.end(), core.points.begin(), core.points.end());
    mesh.tets = std::move(core.tets);
    mesh.boundary_faces = boundary.triangles;
    mesh.boundary_patch.assign(boundary.triangles.size(), 0);
    // The boundary recovery keeps the tets inside a cavity's surface (the
    // hull's are carved away): only the region's are kept.
    TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
    keep_tets(mesh, adjacency, enclosed_tets(mesh, adjacency, nb));
    // Points Gmsh could not insert (it reports them and goes on) are left out.
    std::vector<char> used(mesh.points.size(), 0);
    for (const Tet& t : mesh.tets)
        for (int32_t v : t) used[v] = 1;
    std::vector<int32_t> renumber(mesh.points.size(), -1);
    for (size_t i = 0; i < nb; ++i) renumber[i] = static_cast<int32_t>(i);
    size_t kept = nb;
    for (size_t i = nb; i < mesh.points.size(); ++i)
        if (used[i]) {
            mesh.points[kept] = mesh.points[i];
            renumber[i] = static_cast<int32_t>(kept++);
        }
    mesh.points.resize(kept);
    for (Tet& t : mesh.tets)
        for (int32_t& v : t) v = renumber[v];
    if (mesh.tets.empty())
        throw StageError("volume", "Gmsh made no tets in the core inside the prism layers" +
                                       (core.last_error.empty() ? std::string() : ": " + core.last_error));
    // Every boundary triangle a face of exactly one tet, every other face of two.
    const TetMeshFacts facts = tet_mesh_facts(mesh, adjacency);
    if (facts.nonpositive_tets != 0 || !facts.boundary_matches)
        throw StageError("volume", "Gmsh's core does not match the prism layers' top: " +
                                       std::to_string(facts.nonpositive_tets) + " flat or inverted tets, " +
                                       std::to_string(facts.boundary_faces) + " boundary faces for " +
                                       std::to_string(boundary.triangles.size()) + " triangles");
    return mesh;
}

} // namespace scalemesh
