// The library face (include/scalemesh/): a phantom surface made here meshed
// through mesh_surface and an image through mesh_image, checked for the facts
// the volume stage guarantees, with nothing but the public header.

#include "scalemesh/scalemesh.h"

#include "api/surfaces.h"
#include "support/temp_dir.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>
#include <utility>

namespace {

using scalemesh::MeshResult;
using scalemesh::SurfaceInput;
using scalemesh::test::icosphere;

std::array<double, 3> point(const MeshResult& m, size_t i)
{
    return {m.points[3 * i], m.points[3 * i + 1], m.points[3 * i + 2]};
}

double det(const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c)
{
    return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

std::array<double, 3> minus(const std::array<double, 3>& a, const std::array<double, 3>& b)
{
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}

// The facts every mesh the library returns must have, whatever the input.
void expect_valid_mesh(const MeshResult& m)
{
    const size_t n = m.point_count(), tets = m.tet_count(), faces = m.boundary_count();
    ASSERT_EQ(m.points.size(), 3 * n);
    ASSERT_EQ(m.tets.size(), 4 * tets);
    ASSERT_EQ(m.boundary_triangles.size(), 3 * faces);
    ASSERT_GT(tets, 0u);
    ASSERT_GT(m.surface_points, 0u);
    ASSERT_LT(m.surface_points, n);

    // Positive tets whose volumes add up to the volume the boundary encloses.
    double tet_volume = 0;
    size_t nonpositive = 0;
    for (size_t t = 0; t < tets; ++t) {
        for (int k = 0; k < 4; ++k) ASSERT_LT(m.tets[4 * t + k], n);
        const auto a = point(m, m.tets[4 * t]);
        const double v = det(minus(point(m, m.tets[4 * t + 1]), a), minus(point(m, m.tets[4 * t + 2]), a),
                             minus(point(m, m.tets[4 * t + 3]), a)) / 6;
        nonpositive += v <= 0;
        tet_volume += v;
    }
    EXPECT_EQ(nonpositive, 0u);
    double enclosed = 0;
    std::map<std::pair<size_t, size_t>, int> edges;
    for (size_t f = 0; f < faces; ++f) {
        const size_t* t = &m.boundary_triangles[3 * f];
        for (int k = 0; k < 3; ++k) {
            ASSERT_LT(t[k], m.surface_points) << "boundary triangles use the surface points only";
            ++edges[{t[k], t[(k + 1) % 3]}];
        }
        enclosed += det(point(m, t[0]), point(m, t[1]), point(m, t[2])) / 6;
    }
    EXPECT_NEAR(tet_volume, enclosed, 1e-9 * enclosed);
    // Closed and consistently oriented: each edge once each way.
    for (const auto& [e, count] : edges) {
        EXPECT_EQ(count, 1);
        EXPECT_EQ(edges.count({e.second, e.first}), 1u);
    }

    // Fields: per point, per tet, per boundary triangle.
    for (const std::vector<double>* field : {&m.D, &m.D_out, &m.d, &m.layers}) {
        ASSERT_EQ(field->size(), n);
        for (size_t i = 0; i < m.surface_points; ++i) EXPECT_FALSE(std::isnan((*field)[i]));
        for (size_t i = m.surface_points; i < n; ++i) EXPECT_TRUE(std::isnan((*field)[i]));
    }
    for (size_t i = 0; i < m.surface_points; ++i) EXPECT_GT(m.d[i], 0);
    ASSERT_EQ(m.point_layer.size(), n);
    for (size_t i = 0; i < m.surface_points; ++i) EXPECT_EQ(m.point_layer[i], 0);
    // Each point's generator is a boundary node (itself on the boundary); a
    // layer point (not a filler) of layer m has one in each layer below.
    ASSERT_EQ(m.point_generator.size(), n);
    ASSERT_EQ(m.point_filler.size(), n);
    std::set<std::pair<int32_t, int32_t>> column;
    for (size_t i = 0; i < n; ++i) {
        ASSERT_GE(m.point_generator[i], 0);
        ASSERT_LT(static_cast<size_t>(m.point_generator[i]), m.surface_points);
        if (i < m.surface_points) {
            EXPECT_EQ(m.point_generator[i], static_cast<int32_t>(i));
            EXPECT_EQ(m.point_filler[i], 0);
        }
        if (!m.point_filler[i]) EXPECT_TRUE(column.insert({m.point_generator[i], m.point_layer[i]}).second);
    }
    size_t layer_points = 0;
    for (const auto& [g, layer] : column)
        if (layer > 0) {
            ++layer_points;
            EXPECT_TRUE(column.count({g, layer - 1})) << "node " << g << " layer " << layer;
        }
    EXPECT_GT(layer_points, m.surface_points); // the tube's wall nodes have layers
    ASSERT_EQ(m.aspect_ratio.size(), tets);
    ASSERT_EQ(m.tet_layer.size(), tets);
    for (double q : m.aspect_ratio) {
        EXPECT_GT(q, 0);
        EXPECT_LE(q, 1 + 1e-12);
    }
    ASSERT_EQ(m.boundary_patch.size(), faces);
    for (int32_t p : m.boundary_patch) {
        ASSERT_GE(p, 0);
        ASSERT_LT(static_cast<size_t>(p), m.patch_names.size());
    }
}

double enclosed_volume(const std::vector<double>& x, const std::vector<size_t>& tri)
{
    double v = 0;
    for (size_t f = 0; f < tri.size(); f += 3) {
        const auto p = [&](size_t i) { return std::array<double, 3>{x[3 * i], x[3 * i + 1], x[3 * i + 2]}; };
        v += det(p(tri[f]), p(tri[f + 1]), p(tri[f + 2])) / 6;
    }
    return v;
}

TEST(Api, MeshesAClosedSurfaceWithTheCaseFileDefaults)
{
    const SurfaceInput sphere = icosphere(5.0, 3);
    scalemesh::MeshOptions options;
    options.threads = 1;
    // The run must not limit the process's parallelism (no tbb::global_control):
    // looked at while it runs.
    const size_t outside = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
    std::vector<std::string> stages;
    size_t during = 0;
    options.progress = [&](const std::string& stage, double seconds, const std::string&) {
        if (seconds >= 0) stages.push_back(stage);
        during = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
    };
    const MeshResult m = scalemesh::mesh_surface(sphere, options);
    expect_valid_mesh(m);
    EXPECT_EQ(during, outside);
    ASSERT_FALSE(stages.empty());
    EXPECT_EQ(stages.front(), "import");
    EXPECT_EQ(stages.back(), "volume");
    EXPECT_EQ(m.patch_names, std::vector<std::string>{"wall"});
    EXPECT_EQ(m.layers_built, "prisms"); // the default layers, built
    // Smoothing conserves the enclosed volume to round-off and remeshing
    // gives back what it takes (remeshing/volume_give_back.h): the boundary
    // triangles enclose the input's volume.
    const double input_volume = enclosed_volume(sphere.points, sphere.triangles);
    std::printf("%zu points (%zu on the surface), %zu tets, %zu boundary triangles; enclosed volume %.9g mm^3, "
                "input %.9g mm^3\n",
                m.point_count(), m.surface_points, m.tet_count(), m.boundary_count(),
                enclosed_volume(m.points, m.boundary_triangles), input_volume);
    EXPECT_NEAR(enclosed_volume(m.points, m.boundary_triangles), input_volume, 1e-9 * input_volume);
    // M layers across: floor(M/2) = 3 at the wall for the default M = 7.
    EXPECT_EQ(*std::max_element(m.layers.begin(), m.layers.begin() + m.surface_points), 3.0);
}

// The layer prisms a mesh keeps whole: for each boundary triangle and layer
// m, the tets whose four points are the columns' points of layers m - 1 and
// m of that triangle's three nodes (read from point_generator, point_filler
// and point_layer). A prism is whole when three such tets use all six of
// its points: in a valid mesh (no overlap) they fill it.
size_t whole_layer_prisms(const MeshResult& m)
{
    struct Fill {
        int tets = 0;
        std::set<size_t> points;
    };
    std::map<std::pair<std::array<int32_t, 3>, int32_t>, Fill> filled; // (triangle, layer) -> its tets
    for (size_t t = 0; t < m.tet_count(); ++t) {
        std::array<int32_t, 3> generators{-1, -1, -1};
        int32_t top = 0, bottom = 1 << 30, distinct = 0;
        bool layered = true;
        for (int k = 0; k < 4; ++k) {
            const size_t p = m.tets[4 * t + k];
            if (m.point_filler[p]) layered = false;
            top = std::max(top, m.point_layer[p]), bottom = std::min(bottom, m.point_layer[p]);
            const int32_t g = m.point_generator[p];
            if (std::find(generators.begin(), generators.begin() + distinct, g) == generators.begin() + distinct) {
                if (distinct == 3) layered = false;
                else generators[distinct++] = g;
            }
        }
        if (!layered || distinct != 3 || top != bottom + 1) continue;
        std::sort(generators.begin(), generators.end());
        Fill& fill = filled[{generators, top}];
        ++fill.tets;
        fill.points.insert(m.tets.begin() + 4 * t, m.tets.begin() + 4 * t + 4);
    }
    size_t whole = 0;
    for (size_t f = 0; f < m.boundary_count(); ++f) {
        std::array<int32_t, 3> g;
        for (int k = 0; k < 3; ++k) g[k] = static_cast<int32_t>(m.boundary_triangles[3 * f + k]);
        std::sort(g.begin(), g.end());
        for (int32_t layer = 1;; ++layer) {
            const auto found = filled.find({g, layer});
            if (found == filled.end()) break;
            if (found->second.tets == 3 && found->second.points.size() == 6) ++whole;
        }
    }
    return whole;
}

// layers = "prisms" reaches the library: nearly every wall triangle's three
// layers are whole prisms, where the paper's Delaunay layers keep far fewer.
TEST(Api, PrismLayersAreWholePrisms)
{
    const SurfaceInput sphere = icosphere(5.0, 3);
    scalemesh::MeshOptions options;
    options.threads = 2;
    options.layers = "prisms";
    const MeshResult prisms = scalemesh::mesh_surface(sphere, options);
    expect_valid_mesh(prisms);
    options.layers = "delaunay";
    const MeshResult delaunay = scalemesh::mesh_surface(sphere, options);
    EXPECT_EQ(prisms.layers_built, "prisms");
    EXPECT_EQ(delaunay.layers_built, "delaunay");
    const double wanted = 3.0 * static_cast<double>(prisms.boundary_count());
    const double whole = static_cast<double>(whole_layer_prisms(prisms)) / wanted;
    const double paper = static_cast<double>(whole_layer_prisms(delaunay)) / (3.0 * delaunay.boundary_count());
    std::printf("whole layer prisms: %.1f%% with layers = \"prisms\", %.1f%% with \"delaunay\"\n", 100 * whole,
                100 * paper);
    EXPECT_GE(whole, 0.95);
    EXPECT_LT(paper, 0.8);
    options.layers = "wedges";
    EXPECT_THROW(scalemesh::mesh_surface(sphere, options), scalemesh::InputError);
}

TEST(Api, DefaultsAreTheCaseFileDefaults)
{
    const scalemesh::MeshOptions o;
    EXPECT_EQ(o.K, 4.2);
    EXPECT_EQ(o.M, 7);
    EXPECT_EQ(o.G, 0.85);
    EXPECT_TRUE(o.L_min.voxels);
    EXPECT_EQ(o.L_min.value, 0.5);
    EXPECT_FALSE(o.L_max.has_value());
    EXPECT_EQ(o.smoothing_sweeps, 10);
    EXPECT_EQ(o.remesh_cycles, 3);
    EXPECT_EQ(o.growth, 1.0);
    EXPECT_EQ(o.first_layer, "edge");
    EXPECT_EQ(o.layers, "prisms");
    EXPECT_EQ(o.threads, 0);
}

TEST(Api, LabelsBecomeBoundaryPatches)
{
    SurfaceInput sphere = icosphere(5.0, 3);
    // Label 1 on triangles whose centroid lies above z = 0, else 0.
    for (size_t f = 0; f < sphere.triangles.size(); f += 3) {
        double z = 0;
        for (int k = 0; k < 3; ++k) z += sphere.points[3 * sphere.triangles[f + k] + 2] / 3;
        sphere.labels.push_back(z > 0 ? 1 : 0);
    }
    sphere.label_names = {"lower"};
    const MeshResult m = scalemesh::mesh_surface(sphere, {});
    expect_valid_mesh(m);
    EXPECT_EQ(m.patch_names, (std::vector<std::string>{"lower", "patch_1"}));
    // Away from the label border (input edges are about 0.6 mm long) each
    // boundary triangle carries the label of the half it lies in.
    size_t checked = 0;
    for (size_t f = 0; f < m.boundary_count(); ++f) {
        double z = 0;
        for (int k = 0; k < 3; ++k) z += m.points[3 * m.boundary_triangles[3 * f + k] + 2] / 3;
        if (std::abs(z) < 1.0) continue;
        EXPECT_EQ(m.boundary_patch[f], z > 0 ? 1 : 0) << "triangle " << f << " at z = " << z;
        ++checked;
    }
    EXPECT_GT(checked, m.boundary_count() / 2);
}

TEST(Api, BadInputThrowsInputErrorSayingWhat)
{
    const SurfaceInput sphere = icosphere(5.0, 1);
    SurfaceInput bad_index = sphere;
    bad_index.triangles[4] = sphere.points.size(); // past the last point
    EXPECT_THROW(scalemesh::mesh_surface(bad_index), scalemesh::InputError);
    SurfaceInput open = sphere;
    open.triangles.resize(open.triangles.size() - 3);
    try {
        scalemesh::mesh_surface(open);
        ADD_FAILURE() << "an open surface was meshed";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(dynamic_cast<const scalemesh::InputError*>(&e), nullptr) << e.what();
        EXPECT_NE(std::string(e.what()).find("input surface"), std::string::npos) << e.what();
    }
    SurfaceInput ragged = sphere;
    ragged.points.pop_back();
    EXPECT_THROW(scalemesh::mesh_surface(ragged), scalemesh::InputError);
    SurfaceInput short_labels = sphere;
    short_labels.labels = {0, 1};
    EXPECT_THROW(scalemesh::mesh_surface(short_labels), scalemesh::InputError);
    scalemesh::MeshOptions bad;
    bad.K = -1;
    try {
        scalemesh::mesh_surface(sphere, bad);
        ADD_FAILURE() << "K = -1 was accepted";
    } catch (const scalemesh::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("K"), std::string::npos) << e.what();
    }
    EXPECT_THROW(scalemesh::mesh_image("/nonexistent/image.vdb"), scalemesh::Error);
}

// Issue 44: an option out of range is refused in the same words by the
// library and by `scalemesh run` reading it from a case file (the options'
// one table checks both), each naming its own source.
TEST(Api, AnOptionOutOfRangeIsRefusedAsTheCaseFileRefusesIt)
{
    const SurfaceInput sphere = icosphere(5.0, 2);
    const scalemesh::TempDir dir;
    const char* binary = std::getenv("SCALEMESH_BINARY");
    ASSERT_NE(binary, nullptr) << "run through ctest";
    const auto after_source = [](const std::string& message, const std::string& source) {
        const size_t at = message.find(source + ": ");
        return at == std::string::npos ? "(no " + source + " in: " + message + ")" : message.substr(at + source.size() + 2);
    };
    for (const auto& [section, key, value, set] :
         std::vector<std::tuple<std::string, std::string, std::string, std::function<void(scalemesh::MeshOptions&)>>>{
             {"sizing", "K", "-1", [](scalemesh::MeshOptions& o) { o.K = -1; }},
             {"smoothing", "sweeps", "20000", [](scalemesh::MeshOptions& o) { o.smoothing_sweeps = 20000; }},
             {"volume", "layers", "\"wedges\"", [](scalemesh::MeshOptions& o) { o.layers = "wedges"; }},
             {"sizing", "L_min", "-2", [](scalemesh::MeshOptions& o) { o.L_min = scalemesh::MeshLength::mm(-2); }}}) {
        scalemesh::MeshOptions options;
        set(options);
        std::string by_library;
        try {
            scalemesh::mesh_surface(sphere, options);
        } catch (const scalemesh::InputError& e) {
            by_library = e.what();
        }
        std::ofstream(dir.path / "scalemesh.toml") << "[input]\nphantom = \"sphere\"\n[" << section << "]\n"
                                                   << key << " = " << value << "\n";
        const std::filesystem::path err = dir.path / "stderr.txt";
        EXPECT_EQ(std::system((std::string(binary) + " run -q '" + dir.path.string() + "' 2>'" + err.string() + "'").c_str()) == 0,
                  false);
        std::ifstream in(err);
        const std::string by_case_file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        EXPECT_EQ(after_source(by_case_file, "scalemesh.toml"), after_source(by_library, "mesh options") + "\n") << key;
    }
}

// An ellipsoid of semi-axes (a, b, c) mm centred in an nx x ny x nz label
// image of the given spacing and origin, stored C-ordered as NumPy holds
// vol[i, j, k]: k fastest.
struct Ellipsoid {
    std::array<int64_t, 3> n{};
    std::array<double, 3> spacing{}, origin{}, semi_axes{};
    std::vector<uint8_t> voxels; // [i][j][k]
    Ellipsoid(std::array<int64_t, 3> n_, std::array<double, 3> spacing_, std::array<double, 3> origin_,
              std::array<double, 3> semi_axes_)
        : n(n_), spacing(spacing_), origin(origin_), semi_axes(semi_axes_), voxels(n[0] * n[1] * n[2])
    {
        for (int64_t i = 0; i < n[0]; ++i)
            for (int64_t j = 0; j < n[1]; ++j)
                for (int64_t k = 0; k < n[2]; ++k) {
                    const std::array<int64_t, 3> index{i, j, k};
                    double r2 = 0;
                    for (int d = 0; d < 3; ++d) {
                        const double x = (index[d] - (n[d] - 1) / 2.0) * spacing[d];
                        r2 += x * x / (semi_axes[d] * semi_axes[d]);
                    }
                    voxels[(i * n[1] + j) * n[2] + k] = r2 < 1 ? 1 : 0;
                }
    }
    scalemesh::ImageView view() const
    {
        scalemesh::ImageView v;
        v.data = voxels.data();
        v.type = scalemesh::ImageView::Type::uint8;
        v.size = n;
        v.strides = {n[1] * n[2], n[2], 1};
        v.spacing = spacing;
        v.origin = origin;
        return v;
    }
    // The same voxels in a MetaImage file (x fastest, as the format has them).
    void write_mha(const std::string& path) const
    {
        std::ofstream out(path, std::ios::binary);
        char number[64];
        const auto three = [&](const std::array<double, 3>& v) {
            std::string text;
            for (double x : v) {
                std::snprintf(number, sizeof number, " %.17g", x);
                text += number;
            }
            return text;
        };
        out << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
            << "TransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset =" << three(origin) << "\nElementSpacing ="
            << three(spacing) << "\nDimSize = " << n[0] << " " << n[1] << " " << n[2]
            << "\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
        for (int64_t k = 0; k < n[2]; ++k)
            for (int64_t j = 0; j < n[1]; ++j)
                for (int64_t i = 0; i < n[0]; ++i) out.put(static_cast<char>(voxels[(i * n[1] + j) * n[2] + k]));
    }
};

std::array<std::array<double, 2>, 3> bounds(const MeshResult& m)
{
    std::array<std::array<double, 2>, 3> out;
    for (int d = 0; d < 3; ++d) out[d] = {1e300, -1e300};
    for (size_t i = 0; i < m.point_count(); ++i)
        for (int d = 0; d < 3; ++d) {
            out[d][0] = std::min(out[d][0], m.points[3 * i + d]);
            out[d][1] = std::max(out[d][1], m.points[3 * i + d]);
        }
    return out;
}

// vol[i, j, k] lies at origin + (i, j, k) * spacing: an ellipsoid long along
// x (index i) gives a mesh long along x, centred where the image's centre
// is; and the same voxels in a MetaImage file give the same mesh.
TEST(Api, MeshesAnArrayAsTheSameVoxelsInAFile)
{
    const Ellipsoid image({26, 12, 10}, {0.5, 0.6, 0.7}, {10, -4, 2.5}, {5.5, 2.6, 2.4});
    const MeshResult m = scalemesh::mesh_image(image.view());
    expect_valid_mesh(m);
    const auto box = bounds(m);
    for (int d = 0; d < 3; ++d) {
        const double centre = image.origin[d] + (image.n[d] - 1) / 2.0 * image.spacing[d];
        EXPECT_NEAR((box[d][0] + box[d][1]) / 2, centre, image.spacing[d]) << "axis " << d;
        // The voxelised ellipsoid reaches within a voxel of each semi-axis.
        EXPECT_NEAR((box[d][1] - box[d][0]) / 2, image.semi_axes[d], image.spacing[d]) << "axis " << d;
    }
    EXPECT_GT(box[0][1] - box[0][0], 1.8 * (box[1][1] - box[1][0]));

    const scalemesh::TempDir dir;
    const std::string file = (dir.path / "ellipsoid.mha").string();
    image.write_mha(file);
    const MeshResult from_file = scalemesh::mesh_image(file);
    EXPECT_EQ(from_file.points, m.points);
    EXPECT_EQ(from_file.tets, m.tets);

    // The same voxels x fastest (a Fortran-ordered array, NIfTI's layout),
    // given by their strides, or by default strides of all 0.
    std::vector<uint8_t> x_fastest(image.voxels.size());
    for (int64_t i = 0; i < image.n[0]; ++i)
        for (int64_t j = 0; j < image.n[1]; ++j)
            for (int64_t k = 0; k < image.n[2]; ++k)
                x_fastest[(k * image.n[1] + j) * image.n[0] + i] = image.voxels[(i * image.n[1] + j) * image.n[2] + k];
    scalemesh::ImageView fortran = image.view();
    fortran.data = x_fastest.data();
    fortran.strides = {1, image.n[0], image.n[0] * image.n[1]};
    EXPECT_EQ(scalemesh::mesh_image(fortran).points, m.points);
    fortran.strides = {0, 0, 0};
    EXPECT_EQ(scalemesh::mesh_image(fortran).points, m.points);
}

TEST(Api, BadImageArraysThrowInputErrorSayingWhat)
{
    const Ellipsoid image({8, 8, 8}, {1, 1, 1}, {0, 0, 0}, {2.5, 2.5, 2.5});
    const auto refused = [](const scalemesh::ImageView& view, const scalemesh::ImageOptions& how, const char* says) {
        try {
            scalemesh::mesh_image(view, {}, how);
            ADD_FAILURE() << "accepted; expected an error saying " << says;
        } catch (const scalemesh::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
        }
    };
    scalemesh::ImageView view = image.view();
    view.spacing[1] = 0;
    refused(view, {}, "spacing 0 along axis 1; spacings must be positive");
    view = image.view();
    view.size[2] = 0;
    refused(view, {}, "every axis needs at least one voxel");
    view = image.view();
    view.data = nullptr;
    refused(view, {}, "null pointer");
    const std::vector<uint8_t> empty(image.voxels.size(), 0);
    view = image.view();
    view.data = empty.data();
    refused(view, {}, "has no nonzero voxel");
    refused(image.view(), {.labels = {7}}, "label 7 not present in the image; labels present: 0, 1");
    refused(image.view(), {.grid = "density"}, "grid names a grid of a .vdb file");
}

TEST(Api, MeshesAnImage)
{
    const scalemesh::TempDir dir;
    const std::string image = (dir.path / "sphere.vdb").string();
    const char* binary = std::getenv("SCALEMESH_BINARY");
    ASSERT_NE(binary, nullptr) << "run the tests through ctest";
    ASSERT_EQ(std::system((std::string(binary) + " phantom sphere --voxel-size 1 -o '" + image + "'").c_str()), 0);
    const MeshResult m = scalemesh::mesh_image(image);
    expect_valid_mesh(m);
}

} // namespace
