#pragma once
// The tets and boundary facets of a CGAL Mesh_3 complex as a Gmsh 2.2 ASCII
// file for gmshToFoam: each boundary facet in the physical surface its
// centroid names, the tets in the physical volume "fluid". Shared by the
// validation peers mesh3_tube.cpp and mesh3_surface.cpp.
#include <CGAL/centroid.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace validation {

struct ComplexCounts {
    std::size_t tets = 0, facets = 0, nodes = 0;
    std::vector<std::size_t> facets_per_surface; // per name of `surfaces`
};

// Writes `complex` to `out` (through `out`.part, renamed once whole).
// `surfaces` names the physical surfaces, tags 1, 2, ...; `surface_of`
// gives a boundary facet's tag from its centroid. Tets are written
// positively oriented, nodes numbered from 1 in the order the tets meet
// them. Empty `error` on success, else what went wrong (nothing is left at
// `out`).
template <class Complex, class SurfaceOf>
ComplexCounts write_complex_msh(const Complex& complex, const std::string& out,
                                const std::vector<std::string>& surfaces, SurfaceOf&& surface_of, std::string& error)
{
    using Triangulation = typename Complex::Triangulation;
    using Point = typename Triangulation::Geom_traits::Point_3;
    ComplexCounts counts;
    counts.facets_per_surface.assign(surfaces.size(), 0);
    std::map<typename Triangulation::Vertex_handle, int> index;
    std::vector<Point> points;
    const auto id = [&](typename Triangulation::Vertex_handle v) {
        const auto [it, added] = index.emplace(v, static_cast<int>(points.size()) + 1);
        if (added) points.push_back(v->point().point());
        return it->second;
    };
    std::vector<std::array<int, 4>> tets;
    for (auto c = complex.cells_in_complex_begin(); c != complex.cells_in_complex_end(); ++c) {
        std::array<int, 4> t{id(c->vertex(0)), id(c->vertex(1)), id(c->vertex(2)), id(c->vertex(3))};
        if (CGAL::orientation(points[t[0] - 1], points[t[1] - 1], points[t[2] - 1], points[t[3] - 1]) ==
            CGAL::NEGATIVE)
            std::swap(t[2], t[3]);
        tets.push_back(t);
    }
    std::vector<std::array<int, 4>> facets; // physical tag, three nodes
    for (auto f = complex.facets_in_complex_begin(); f != complex.facets_in_complex_end(); ++f) {
        std::array<int, 3> v{};
        for (int k = 0; k < 3; ++k) {
            const auto it = index.find(f->first->vertex((f->second + 1 + k) & 3));
            if (it == index.end()) {
                error = "a boundary facet's vertex is in no tet of the complex";
                return counts;
            }
            v[k] = it->second;
        }
        const int tag = surface_of(CGAL::centroid(points[v[0] - 1], points[v[1] - 1], points[v[2] - 1]));
        ++counts.facets_per_surface[tag - 1];
        facets.push_back({tag, v[0], v[1], v[2]});
    }
    if (tets.empty() || facets.empty()) {
        error = "Mesh_3 gave an empty complex";
        return counts;
    }

    std::ofstream file(out + ".part");
    file.precision(17);
    const int volume_tag = static_cast<int>(surfaces.size()) + 1;
    file << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n" << surfaces.size() + 1 << "\n";
    for (std::size_t s = 0; s < surfaces.size(); ++s) file << "2 " << s + 1 << " \"" << surfaces[s] << "\"\n";
    file << "3 " << volume_tag << " \"fluid\"\n$EndPhysicalNames\n$Nodes\n" << points.size() << "\n";
    for (std::size_t i = 0; i < points.size(); ++i)
        file << i + 1 << " " << points[i].x() << " " << points[i].y() << " " << points[i].z() << "\n";
    file << "$EndNodes\n$Elements\n" << facets.size() + tets.size() << "\n";
    std::size_t n = 0;
    for (const auto& f : facets)
        file << ++n << " 2 2 " << f[0] << " " << f[0] << " " << f[1] << " " << f[2] << " " << f[3] << "\n";
    for (const auto& t : tets)
        file << ++n << " 4 2 " << volume_tag << " " << volume_tag << " " << t[0] << " " << t[1] << " " << t[2]
             << " " << t[3] << "\n";
    file << "$EndElements\n";
    file.close();
    if (!file || std::rename((out + ".part").c_str(), out.c_str()) != 0) {
        error = "cannot write " + out;
        std::remove((out + ".part").c_str());
        return counts;
    }
    counts.tets = tets.size(), counts.facets = facets.size(), counts.nodes = points.size();
    return counts;
}

} // namespace validation
