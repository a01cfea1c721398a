#include "references.h"

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/make_mesh_3.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <cstring>

namespace scalemesh::bench {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using CgalSurface = CGAL::Surface_mesh<Kernel::Point_3>;

CgalSurface to_cgal(const SurfaceMesh& surface)
{
    CgalSurface mesh;
    std::vector<CgalSurface::Vertex_index> vertices;
    vertices.reserve(surface.points.size());
    for (const Vec3& p : surface.points) vertices.push_back(mesh.add_vertex({p.x, p.y, p.z}));
    for (const Triangle& t : surface.triangles) mesh.add_face(vertices[t[0]], vertices[t[1]], vertices[t[2]]);
    return mesh;
}

SurfaceMesh from_cgal(const CgalSurface& mesh)
{
    SurfaceMesh surface;
    std::vector<int32_t> index(mesh.number_of_vertices() + mesh.number_of_removed_vertices(), -1);
    for (const auto v : mesh.vertices()) {
        index[v] = static_cast<int32_t>(surface.points.size());
        const auto& p = mesh.point(v);
        surface.points.push_back({p.x(), p.y(), p.z()});
    }
    for (const auto f : mesh.faces()) {
        Triangle t{};
        int k = 0;
        for (const auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) t[k++] = index[v];
        surface.triangles.push_back(t);
    }
    return surface;
}

// The label grid as an 8-bit CGAL image over its active bounding box with two
// background voxels of margin, so that the domain closes inside the image.
// CGAL puts voxel (i, j, k) at t + (i, j, k) v, the phantom at its centre.
CGAL::Image_3 label_image(const openvdb::FloatGrid& labels)
{
    const openvdb::CoordBBox box = labels.evalActiveVoxelBoundingBox();
    const openvdb::Coord lo = box.min() - openvdb::Coord(2), hi = box.max() + openvdb::Coord(2);
    const openvdb::Vec3d h = labels.voxelSize();
    const size_t nx = hi.x() - lo.x() + 1, ny = hi.y() - lo.y() + 1, nz = hi.z() - lo.z() + 1;
    _image* image = _createImage(nx, ny, nz, 1, h.x(), h.y(), h.z(), 1, WK_FIXED, SGN_UNSIGNED);
    const openvdb::Vec3d origin = labels.transform().indexToWorld(lo.asVec3d());
    image->tx = static_cast<float>(origin.x());
    image->ty = static_cast<float>(origin.y());
    image->tz = static_cast<float>(origin.z());
    auto* data = static_cast<unsigned char*>(image->data);
    std::memset(data, 0, nx * ny * nz);
    auto accessor = labels.getConstAccessor();
    for (size_t k = 0; k < nz; ++k)
        for (size_t j = 0; j < ny; ++j)
            for (size_t i = 0; i < nx; ++i) {
                const openvdb::Coord c(lo.x() + int(i), lo.y() + int(j), lo.z() + int(k));
                data[(k * ny + j) * nx + i] = accessor.getValue(c) > 0.5f ? 1 : 0; // x fastest
            }
    return CGAL::Image_3(image);
}

} // namespace

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

double median(std::vector<double> values)
{
    if (values.empty()) return 0;
    std::sort(values.begin(), values.end());
    const size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double median_of_reported(int repeats, const std::function<double()>& timed_work)
{
    std::vector<double> times;
    for (int i = 0; i < std::max(repeats, 1); ++i) times.push_back(timed_work());
    return median(times);
}

double median_seconds(int repeats, const std::function<void()>& work)
{
    return median_of_reported(repeats, [&] {
        const auto start = Clock::now();
        work();
        return seconds_since(start);
    });
}

ReferenceRun openvdb_volume_to_mesh(const openvdb::FloatGrid& grid, double iso)
{
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    const auto start = Clock::now();
    openvdb::tools::volumeToMesh(grid, points, triangles, quads, iso, 0.0);
    return {seconds_since(start), triangles.size() + 2 * quads.size()};
}

ReferenceRun cgal_isotropic_remeshing(const SurfaceMesh& surface, double target_edge_mm, int iterations,
                                      SurfaceMesh* remeshed)
{
    CgalSurface mesh = to_cgal(surface);
    const auto start = Clock::now();
    CGAL::Polygon_mesh_processing::isotropic_remeshing(faces(mesh), target_edge_mm, mesh,
                                                       CGAL::parameters::number_of_iterations(iterations));
    const double seconds = seconds_since(start);
    if (remeshed) *remeshed = from_cgal(mesh);
    return {seconds, static_cast<size_t>(mesh.number_of_faces())};
}

ReferenceRun cgal_delaunay(const std::vector<Vec3>& points)
{
    std::vector<Kernel::Point_3> cgal_points;
    cgal_points.reserve(points.size());
    for (const Vec3& p : points) cgal_points.emplace_back(p.x, p.y, p.z);
    const auto start = Clock::now();
    const CGAL::Delaunay_triangulation_3<Kernel> dt(cgal_points.begin(), cgal_points.end());
    return {seconds_since(start), static_cast<size_t>(dt.number_of_finite_cells())};
}

ReferenceRun cgal_mesh_3(const openvdb::FloatGrid& labels, const Mesh3Criteria& c)
{
    using Domain = CGAL::Labeled_mesh_domain_3<Kernel>;
    using Triangulation = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
    using Complex = CGAL::Mesh_complex_3_in_triangulation_3<Triangulation>;
    using Criteria = CGAL::Mesh_criteria_3<Triangulation>;
    namespace params = CGAL::parameters;

    const CGAL::Image_3 image = label_image(labels);
    const auto start = Clock::now();
    const Domain domain = Domain::create_labeled_image_mesh_domain(image);
    const Criteria criteria(params::facet_angle = c.facet_angle, params::facet_size = c.facet_size,
                            params::facet_distance = c.facet_distance,
                            params::cell_radius_edge_ratio = c.cell_radius_edge_ratio, params::cell_size = c.cell_size);
    const Complex complex = CGAL::make_mesh_3<Complex>(domain, criteria);
    return {seconds_since(start), static_cast<size_t>(complex.number_of_cells_in_complex())};
}

} // namespace scalemesh::bench
