// mesh3_tube: CGAL Mesh_3's isotropic tet mesh of the validation tube (a
// cylinder of radius 3 mm between the planes z = -12 and +12 mm), written as
// a Gmsh 2.2 ASCII file with the physical surfaces wall, inlet (z = -12) and
// outlet (z = +12) and the physical volume fluid, for gmshToFoam. It is the
// CGAL peer of validation/tube_validation.py.
//
//     mesh3_tube H OUT.msh
//
// H (mm) bounds every size criterion: the edges of the two protected cap
// circles, the surface Delaunay balls and the tets' circumradii; facet angle
// at least 25 degrees, surface distance at most H / 20, radius-edge ratio at
// most 3; default perturbation and exudation, as bench/references.cpp runs
// Mesh_3. The cap circles are protected features, so the rims stay sharp.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_domain_with_polyline_features_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/make_mesh_3.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <vector>

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Domain = CGAL::Mesh_domain_with_polyline_features_3<CGAL::Labeled_mesh_domain_3<Kernel>>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;

constexpr double radius = 3.0;  // mm
constexpr double half = 12.0;   // mm
constexpr double pi = 3.14159265358979323846;

// Negative inside the clipped cylinder.
double tube(const Point& p)
{
    return std::max(std::hypot(p.x(), p.y()) - radius, std::abs(p.z()) - half);
}

// The two rims, closed polylines of many more points than the mesh's edges
// (Mesh_3 places its own protecting balls along them).
std::vector<std::vector<Point>> rims()
{
    std::vector<std::vector<Point>> lines;
    for (const double z : {-half, half}) {
        std::vector<Point> line;
        const int n = 720;
        for (int i = 0; i <= n; ++i) {
            const double a = 2 * pi * (i % n) / n;
            line.emplace_back(radius * std::cos(a), radius * std::sin(a), z);
        }
        lines.push_back(std::move(line));
    }
    return lines;
}

} // namespace

int main(int argc, char** argv)
{
    if (argc != 3) {
        std::cerr << "usage: mesh3_tube H OUT.msh  (H: the size bound in mm, e.g. 0.8)\n";
        return 2;
    }
    char* end = nullptr;
    const double h = std::strtod(argv[1], &end);
    if (end == argv[1] || *end != '\0' || !(h > 0.05 && h < 10)) {
        std::cerr << "mesh3_tube: size bound '" << argv[1] << "' is not a number of mm in (0.05, 10)\n";
        return 2;
    }
    namespace params = CGAL::parameters;
    Domain domain = Domain::create_implicit_mesh_domain(
        tube, Kernel::Sphere_3(CGAL::ORIGIN, (half + 1) * (half + 1) + (radius + 1) * (radius + 1)),
        params::relative_error_bound = 1e-7);
    const auto lines = rims();
    domain.add_features(lines.begin(), lines.end());
    const Criteria criteria(params::edge_size = h, params::facet_angle = 25, params::facet_size = h,
                            params::facet_distance = h / 20, params::cell_radius_edge_ratio = 3,
                            params::cell_size = h);
    const Complex complex = CGAL::make_mesh_3<Complex>(domain, criteria);

    // The vertices of the complex's tets, numbered from 1 in the order met.
    std::map<Triangulation::Vertex_handle, int> index;
    std::vector<Point> points;
    const auto id = [&](Triangulation::Vertex_handle v) {
        const auto [it, added] = index.emplace(v, static_cast<int>(points.size()) + 1);
        if (added) points.push_back(v->point().point());
        return it->second;
    };
    std::vector<std::array<int, 4>> tets;
    for (auto c = complex.cells_in_complex_begin(); c != complex.cells_in_complex_end(); ++c) {
        std::array<int, 4> t{id(c->vertex(0)), id(c->vertex(1)), id(c->vertex(2)), id(c->vertex(3))};
        const Point& a = points[t[0] - 1];
        if (CGAL::orientation(a, points[t[1] - 1], points[t[2] - 1], points[t[3] - 1]) == CGAL::NEGATIVE)
            std::swap(t[2], t[3]);
        tets.push_back(t);
    }
    // Boundary facets, named by where their centroid lies.
    std::vector<std::array<int, 4>> facets;  // physical tag, three nodes
    for (auto f = complex.facets_in_complex_begin(); f != complex.facets_in_complex_end(); ++f) {
        std::array<int, 3> v{};
        for (int k = 0; k < 3; ++k) {
            const auto vh = f->first->vertex((f->second + 1 + k) & 3);
            const auto it = index.find(vh);
            if (it == index.end()) {
                std::cerr << "mesh3_tube: a boundary facet's vertex is in no tet of the complex\n";
                return 1;
            }
            v[k] = it->second;
        }
        const double z = (points[v[0] - 1].z() + points[v[1] - 1].z() + points[v[2] - 1].z()) / 3;
        const int tag = z < -half + 1e-6 * half ? 2 : z > half - 1e-6 * half ? 3 : 1;
        facets.push_back({tag, v[0], v[1], v[2]});
    }
    if (tets.empty() || facets.empty()) {
        std::cerr << "mesh3_tube: Mesh_3 gave an empty complex\n";
        return 1;
    }

    const std::string out = argv[2];
    std::ofstream file(out + ".part");
    file.precision(17);
    file << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n4\n2 1 \"wall\"\n2 2 \"inlet\"\n"
            "2 3 \"outlet\"\n3 10 \"fluid\"\n$EndPhysicalNames\n$Nodes\n"
         << points.size() << "\n";
    for (size_t i = 0; i < points.size(); ++i)
        file << i + 1 << " " << points[i].x() << " " << points[i].y() << " " << points[i].z() << "\n";
    file << "$EndNodes\n$Elements\n" << facets.size() + tets.size() << "\n";
    size_t n = 0;
    for (const auto& f : facets)
        file << ++n << " 2 2 " << f[0] << " " << f[0] << " " << f[1] << " " << f[2] << " " << f[3] << "\n";
    for (const auto& t : tets)
        file << ++n << " 4 2 10 10 " << t[0] << " " << t[1] << " " << t[2] << " " << t[3] << "\n";
    file << "$EndElements\n";
    file.close();
    if (!file || std::rename((out + ".part").c_str(), out.c_str()) != 0) {
        std::cerr << "mesh3_tube: cannot write " << out << "\n";
        std::remove((out + ".part").c_str());
        return 1;
    }
    std::cout << tets.size() << " tets, " << facets.size() << " boundary triangles, " << points.size()
              << " nodes\n";
    return 0;
}
