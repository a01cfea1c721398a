#include "volume/self_intersections.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <utility>

namespace scalemesh {

SelfIntersections self_intersections(const SurfaceMesh& surface, size_t keep)
{
    using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
    using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
    Mesh mesh;
    std::vector<Mesh::Vertex_index> vertex;
    vertex.reserve(surface.points.size());
    for (const Vec3& p : surface.points) vertex.push_back(mesh.add_vertex(Kernel::Point_3(p.x, p.y, p.z)));
    std::vector<int32_t> triangle_of_face; // CGAL face index -> triangle id
    triangle_of_face.reserve(surface.triangles.size());
    for (size_t t = 0; t < surface.triangles.size(); ++t) {
        const Triangle& tri = surface.triangles[t];
        if (mesh.add_face(vertex[tri[0]], vertex[tri[1]], vertex[tri[2]]) != Mesh::null_face())
            triangle_of_face.push_back(static_cast<int32_t>(t));
    }
    std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
    CGAL::Polygon_mesh_processing::self_intersections<CGAL::Parallel_if_available_tag>(mesh, std::back_inserter(pairs));
    SelfIntersections out;
    out.pairs = static_cast<int64_t>(pairs.size());
    std::vector<std::array<int32_t, 2>> ids;
    ids.reserve(pairs.size());
    for (const auto& [f, g] : pairs) {
        const int32_t a = triangle_of_face[f.idx()], b = triangle_of_face[g.idx()];
        ids.push_back({std::min(a, b), std::max(a, b)});
    }
    std::sort(ids.begin(), ids.end());
    ids.resize(std::min(ids.size(), keep));
    out.first = std::move(ids);
    return out;
}

} // namespace scalemesh
