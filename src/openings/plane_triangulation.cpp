#include "openings/plane_triangulation.h"

#include "core/errors.h"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <string>

namespace scalemesh::openings {

PlaneBasis::PlaneBasis(const Vec3& n)
{
    const Vec3 a = std::abs(n.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    e1 = normalized(a - dot(a, n) * n);
    e2 = cross(n, e1);
}

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<int32_t, Kernel>;
struct FaceInfo {
    int nesting = -1; // loops around the face; -1 until marked
    int piece = -1;
};
using FaceBase = CGAL::Triangulation_face_base_with_info_2<FaceInfo, Kernel,
                                                            CGAL::Constrained_triangulation_face_base_2<Kernel>>;
using Tds = CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_predicates_tag>;

// Nesting depth of every face: 0 outside all loops, +1 across each
// constrained edge (the marking of CGAL's polygon triangulation example).
void mark_nesting(CDT& cdt)
{
    std::deque<std::pair<CDT::Face_handle, int>> border{{cdt.infinite_face(), 0}};
    while (!border.empty()) {
        const auto [start, level] = border.front();
        border.pop_front();
        if (start->info().nesting != -1) continue;
        std::deque<CDT::Face_handle> queue{start};
        while (!queue.empty()) {
            const CDT::Face_handle f = queue.front();
            queue.pop_front();
            if (f->info().nesting != -1) continue;
            f->info().nesting = level;
            for (int i = 0; i < 3; ++i) {
                const CDT::Face_handle n = f->neighbor(i);
                if (n->info().nesting != -1) continue;
                if (cdt.is_constrained({f, i}))
                    border.emplace_back(n, level + 1);
                else
                    queue.push_back(n);
            }
        }
    }
}

} // namespace

std::vector<PlanePiece> triangulate_loops(const std::vector<double>& u, const std::vector<double>& v,
                                          const std::vector<std::vector<int32_t>>& loops, const char* what)
{
    const size_t n = u.size();
    std::vector<std::pair<Kernel::Point_2, int32_t>> input;
    input.reserve(n);
    for (size_t i = 0; i < n; ++i) input.emplace_back(Kernel::Point_2(u[i], v[i]), static_cast<int32_t>(i));

    CDT cdt;
    cdt.insert(input.begin(), input.end());
    if (cdt.number_of_vertices() != n)
        throw StageError(what, std::to_string(n - cdt.number_of_vertices()) +
                                   " points of a cap coincide in its plane; the rim folds onto itself");
    std::vector<CDT::Vertex_handle> handle(n);
    for (auto vh : cdt.finite_vertex_handles()) handle[vh->info()] = vh;

    try {
        for (const auto& loop : loops)
            for (size_t k = 0; k < loop.size(); ++k)
                cdt.insert_constraint(handle[loop[k]], handle[loop[(k + 1) % loop.size()]]);
    } catch (const std::exception&) {
        throw StageError(what, "the rim of a cap crosses itself in the cap plane");
    }
    if (cdt.number_of_vertices() != n)
        throw StageError(what, "the rim of a cap crosses itself in the cap plane");
    for (const auto& loop : loops)
        for (size_t k = 0; k < loop.size(); ++k) {
            CDT::Face_handle f;
            int i;
            if (!cdt.is_edge(handle[loop[k]], handle[loop[(k + 1) % loop.size()]], f, i))
                throw StageError(what, "a point lies on the rim of a cap between two rim nodes");
        }

    mark_nesting(cdt);

    // Pieces: inside faces joined across unconstrained edges.
    std::vector<PlanePiece> pieces;
    for (auto seed : cdt.finite_face_handles()) {
        if (seed->info().nesting % 2 != 1 || seed->info().piece != -1) continue;
        const int id = static_cast<int>(pieces.size());
        PlanePiece piece;
        double su = 0, sv = 0;
        std::deque<CDT::Face_handle> queue{seed};
        seed->info().piece = id;
        while (!queue.empty()) {
            const CDT::Face_handle f = queue.front();
            queue.pop_front();
            const std::array<int32_t, 3> tri = {f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()};
            const double area = 0.5 * ((u[tri[1]] - u[tri[0]]) * (v[tri[2]] - v[tri[0]]) -
                                       (u[tri[2]] - u[tri[0]]) * (v[tri[1]] - v[tri[0]]));
            piece.triangles.push_back(tri);
            piece.area += area;
            su += area * (u[tri[0]] + u[tri[1]] + u[tri[2]]) / 3;
            sv += area * (v[tri[0]] + v[tri[1]] + v[tri[2]]) / 3;
            for (int i = 0; i < 3; ++i) {
                const CDT::Face_handle nb = f->neighbor(i);
                if (cdt.is_constrained({f, i}) || cdt.is_infinite(nb) || nb->info().piece != -1) continue;
                nb->info().piece = id;
                queue.push_back(nb);
            }
        }
        piece.cu = piece.area > 0 ? su / piece.area : 0;
        piece.cv = piece.area > 0 ? sv / piece.area : 0;
        pieces.push_back(std::move(piece));
    }
    std::stable_sort(pieces.begin(), pieces.end(),
                     [](const PlanePiece& a, const PlanePiece& b) { return a.area > b.area; });
    return pieces;
}

} // namespace scalemesh::openings
