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

#include "complex_msh.h"

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

    // Boundary facets, named by where their centroid lies.
    std::string error;
    const validation::ComplexCounts counts = validation::write_complex_msh(
        complex, argv[2], {"wall", "inlet", "outlet"},
        [](const Point& c) { return c.z() < -half + 1e-6 * half ? 2 : c.z() > half - 1e-6 * half ? 3 : 1; }, error);
    if (!error.empty()) {
        std::cerr << "mesh3_tube: " << error << "\n";
        return 1;
    }
    std::cout << counts.tets << " tets, " << counts.facets << " boundary triangles, " << counts.nodes << " nodes\n";
    return 0;
}
