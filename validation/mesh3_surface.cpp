// mesh3_surface: CGAL Mesh_3's isotropic tet mesh of a closed STL surface,
// written as a Gmsh 2.2 ASCII file with a physical surface per opening, the
// rest `wall`, and the physical volume `fluid`, for gmshToFoam. It is the
// CGAL peer of validation/multiscale_validation.py (--mesh3-h, --mesh3-radius).
//
//     mesh3_surface SURFACE.stl OUT.msh --size H [--min-size HMIN]
//         [--radius-factor F --centreline FILE] [--opening NAME PX PY PZ NX NY NZ R]...
//
// The surface is Polyhedral_mesh_domain_with_features_3 with its sharp edges
// (dihedral angle sharper than 60 degrees: the rims of flat end discs, at 90
// degrees, but not the edges between the STL's facets around a cylinder)
// protected as features, so the rims stay sharp. The criteria are those of
// mesh3_tube.cpp: facet angle at least 25 degrees, radius-edge ratio at most
// 3, surface distance at most size / 20, default perturbation and exudation.
// Uniform (no --radius-factor): size = H (mm) for the feature edges, the
// surface Delaunay balls and the tets' circumradii. Radius-proportional:
// size(x) = clamp(F r(x), HMIN, H), r(x) the radius of the centreline
// segment nearest x, FILE a line `x0 y0 z0 x1 y1 z1 r0 r1` (mm) per segment,
// the radius linear along it; HMIN defaults to H / 16. A boundary facet whose
// centroid lies within 1e-3 mm of an opening's plane (point P, normal N) and
// within R mm of P is that opening's.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/IO/polygon_soup_io.h>
#include <CGAL/boost/graph/helpers.h>
#include <CGAL/make_mesh_3.h>

#include "complex_msh.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Vector = Kernel::Vector_3;
using Surface = CGAL::Surface_mesh<Point>;
using Domain = CGAL::Polyhedral_mesh_domain_with_features_3<Kernel, Surface>;
using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation>;
using Criteria = CGAL::Mesh_criteria_3<Triangulation>;

constexpr double feature_angle = 60;  // degrees
constexpr double plane_tolerance = 1e-3;  // mm

struct Segment {
    Point a, b;
    double ra, rb;
};

struct Opening {
    std::string name;
    Point point;
    Vector normal;  // unit
    double radius;
};

// size(x) / divisor with size(x) = clamp(factor r(x), lo, hi), r(x) the
// radius at the nearest point of the nearest centreline segment.
struct Radius_sizing {
    const std::vector<Segment>* segments;
    double factor, lo, hi, divisor;

    double operator()(const Point& p, int, const Domain::Index&) const
    {
        double best = std::numeric_limits<double>::infinity(), r = 0;
        for (const Segment& s : *segments) {
            const Vector d = s.b - s.a;
            const double t = std::clamp((p - s.a) * d / std::max(d.squared_length(), 1e-300), 0.0, 1.0);
            const double dist = CGAL::squared_distance(p, s.a + t * d);
            if (dist < best) {
                best = dist;
                r = s.ra + t * (s.rb - s.ra);
            }
        }
        return std::clamp(factor * r, lo, hi) / divisor;
    }
};

[[noreturn]] void usage(const std::string& why)
{
    std::cerr << "mesh3_surface: " << why
              << "\nusage: mesh3_surface SURFACE.stl OUT.msh --size H [--min-size HMIN] [--radius-factor F "
                 "--centreline FILE] [--opening NAME PX PY PZ NX NY NZ R]...\n";
    std::exit(2);
}

double number(const char* text, const std::string& what)
{
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (end == text || *end != '\0' || !std::isfinite(v)) usage(what + " '" + text + "' is not a number");
    return v;
}

std::vector<Segment> read_centreline(const std::string& path)
{
    std::ifstream in(path);
    if (!in) usage("cannot read the centreline " + path);
    std::vector<Segment> out;
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream words(line);
        std::array<double, 8> v{};
        if (!(words >> v[0])) continue;  // a blank line
        for (int k = 1; k < 8; ++k)
            if (!(words >> v[k])) usage("centreline " + path + ": a line is not x0 y0 z0 x1 y1 z1 r0 r1");
        if (!(v[6] > 0 && v[7] > 0)) usage("centreline " + path + ": radii must be positive");
        out.push_back({Point(v[0], v[1], v[2]), Point(v[3], v[4], v[5]), v[6], v[7]});
    }
    if (out.empty()) usage("centreline " + path + " has no segment");
    return out;
}

// The STL as a closed, consistently oriented surface bounding its volume.
Surface read_surface(const std::string& path)
{
    namespace PMP = CGAL::Polygon_mesh_processing;
    std::vector<Point> points;
    std::vector<std::vector<std::size_t>> polygons;
    if (!CGAL::IO::read_polygon_soup(path, points, polygons) || polygons.empty())
        usage("cannot read a surface from " + path);
    PMP::repair_polygon_soup(points, polygons);
    PMP::orient_polygon_soup(points, polygons);
    Surface surface;
    PMP::polygon_soup_to_polygon_mesh(points, polygons, surface);
    if (!CGAL::is_closed(surface) || !CGAL::is_triangle_mesh(surface))
        usage(path + " is not a closed triangle surface");
    PMP::orient_to_bound_a_volume(surface);
    return surface;
}

} // namespace

int main(int argc, char** argv)
{
    if (argc < 3) usage("SURFACE.stl and OUT.msh are required");
    const std::string stl = argv[1], out = argv[2];
    double h = 0, h_min = 0, factor = 0;
    std::string centreline;
    std::vector<Opening> openings;
    for (int i = 3; i < argc; ++i) {
        const std::string arg = argv[i];
        const auto need = [&](int n) {
            if (i + n >= argc) usage(arg + " needs " + std::to_string(n) + " value(s)");
        };
        if (arg == "--size") {
            need(1);
            h = number(argv[++i], "--size");
        } else if (arg == "--min-size") {
            need(1);
            h_min = number(argv[++i], "--min-size");
        } else if (arg == "--radius-factor") {
            need(1);
            factor = number(argv[++i], "--radius-factor");
            if (!(factor > 0)) usage("--radius-factor must be positive");
        } else if (arg == "--centreline") {
            need(1);
            centreline = argv[++i];
        } else if (arg == "--opening") {
            need(8);
            Opening o;
            o.name = argv[++i];
            double v[7];
            for (double& x : v) x = number(argv[++i], "--opening " + o.name);
            o.point = Point(v[0], v[1], v[2]);
            const Vector n(v[3], v[4], v[5]);
            if (!(n.squared_length() > 0) || !(v[6] > 0)) usage("--opening " + o.name + ": zero normal or radius");
            o.normal = n / std::sqrt(n.squared_length());
            o.radius = v[6];
            if (o.name == "wall" || o.name == "fluid") usage("--opening: the name " + o.name + " is taken");
            openings.push_back(o);
        } else {
            usage("unknown argument " + arg);
        }
    }
    if (!(h > 0.01 && h < 100)) usage("--size H (mm, in (0.01, 100)) is required");
    if ((factor > 0) != !centreline.empty()) usage("--radius-factor and --centreline go together");
    if (h_min == 0) h_min = h / 16;
    if (!(h_min > 0 && h_min <= h)) usage("--min-size must be in (0, H]");

    const auto start = std::chrono::steady_clock::now();
    Surface surface = read_surface(stl);
    Domain domain(surface);
    domain.detect_features(feature_angle);

    namespace params = CGAL::parameters;
    const auto mesh = [&](const auto& size, const auto& distance) {
        const Criteria criteria(params::edge_size = size, params::facet_angle = 25, params::facet_size = size,
                                params::facet_distance = distance, params::cell_radius_edge_ratio = 3,
                                params::cell_size = size);
        return CGAL::make_mesh_3<Complex>(domain, criteria);
    };
    std::vector<Segment> segments;
    Complex complex;
    if (factor > 0) {
        segments = read_centreline(centreline);
        complex = mesh(Radius_sizing{&segments, factor, h_min, h, 1}, Radius_sizing{&segments, factor, h_min, h, 20});
    } else {
        complex = mesh(h, h / 20);
    }

    // Boundary facets: physical tag 1 (wall) or 2 + the opening's position.
    std::vector<std::string> names{"wall"};
    for (const Opening& o : openings) names.push_back(o.name);
    std::string error;
    const validation::ComplexCounts counts = validation::write_complex_msh(
        complex, out, names,
        [&](const Point& c) {
            for (std::size_t o = 0; o < openings.size(); ++o) {
                const Vector d = c - openings[o].point;
                if (std::abs(d * openings[o].normal) < plane_tolerance &&
                    d.squared_length() < openings[o].radius * openings[o].radius)
                    return static_cast<int>(o) + 2;
            }
            return 1;
        },
        error);
    if (!error.empty()) {
        std::cerr << "mesh3_surface: " << error << "\n";
        return 1;
    }
    for (std::size_t o = 0; o < openings.size(); ++o)
        if (counts.facets_per_surface[o + 1] == 0) {
            std::cerr << "mesh3_surface: no boundary facet lies on the opening " << openings[o].name << "\n";
            std::remove(out.c_str());
            return 1;
        }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << counts.tets << " tets, " << counts.facets << " boundary triangles, " << counts.nodes << " nodes in "
              << seconds << " s\n";
    return 0;
}
