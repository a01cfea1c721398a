#pragma once
// Shapes built in code and a scratch directory for the exporter tests.

#include "core/surface_mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <string>
#include <unistd.h>

namespace scalemesh::test {

inline SurfaceMesh translated(SurfaceMesh mesh, const Vec3& offset)
{
    for (Vec3& p : mesh.points) p += offset;
    return mesh;
}

// Regular octahedron with vertices at distance r on the axes, outward normals.
inline SurfaceMesh octahedron(double r)
{
    SurfaceMesh mesh;
    mesh.points = {{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
    for (int sx : {0, 1})
        for (int sy : {0, 1})
            for (int sz : {0, 1}) {
                // (x, y, z) in the (+, +, +) octant is counter-clockwise seen from
                // outside; each mirror flips the orientation.
                Triangle t{sx, 2 + sy, 4 + sz};
                if ((sx + sy + sz) % 2 == 1) std::swap(t[1], t[2]);
                mesh.triangles.push_back(t);
            }
    return mesh;
}

// Icosphere of radius r: an icosahedron subdivided `levels` times, vertices
// shared, outward normals.
inline SurfaceMesh icosphere(double r, int levels)
{
    const double g = (1 + std::sqrt(5.0)) / 2;
    SurfaceMesh mesh;
    mesh.points = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                   {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
    mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                      {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int level = 0; level < levels; ++level) {
        std::map<std::pair<int32_t, int32_t>, int32_t> midpoint;
        const auto middle = [&](int32_t a, int32_t b) {
            const auto key = std::minmax(a, b);
            const auto [it, inserted] = midpoint.try_emplace({key.first, key.second}, int32_t(mesh.points.size()));
            if (inserted) mesh.points.push_back(0.5 * (mesh.points[a] + mesh.points[b]));
            return it->second;
        };
        std::vector<Triangle> finer;
        for (const Triangle& t : mesh.triangles) {
            const int32_t ab = middle(t[0], t[1]), bc = middle(t[1], t[2]), ca = middle(t[2], t[0]);
            finer.insert(finer.end(), {{t[0], ab, ca}, {t[1], bc, ab}, {t[2], ca, bc}, {ab, bc, ca}});
        }
        mesh.triangles = std::move(finer);
    }
    for (Vec3& p : mesh.points) p = r * normalized(p);
    return mesh;
}

// Latitude-longitude sphere of radius r with single-vertex poles.
inline SurfaceMesh uv_sphere(double r, int longitudes, int latitudes)
{
    SurfaceMesh mesh;
    mesh.points.push_back({0, 0, r});
    for (int j = 1; j < latitudes; ++j) {
        const double theta = std::numbers::pi * j / latitudes;
        for (int i = 0; i < longitudes; ++i) {
            const double phi = 2 * std::numbers::pi * i / longitudes;
            mesh.points.push_back({r * std::sin(theta) * std::cos(phi), r * std::sin(theta) * std::sin(phi),
                                   r * std::cos(theta)});
        }
    }
    const auto south = int32_t(mesh.points.size());
    mesh.points.push_back({0, 0, -r});
    const auto ring = [&](int j, int i) { return int32_t(1 + (j - 1) * longitudes + (i % longitudes)); };
    for (int i = 0; i < longitudes; ++i) {
        mesh.triangles.push_back({0, ring(1, i), ring(1, i + 1)});
        for (int j = 1; j + 1 < latitudes; ++j) {
            mesh.triangles.push_back({ring(j, i), ring(j + 1, i), ring(j + 1, i + 1)});
            mesh.triangles.push_back({ring(j, i), ring(j + 1, i + 1), ring(j, i + 1)});
        }
        mesh.triangles.push_back({south, ring(latitudes - 1, i + 1), ring(latitudes - 1, i)});
    }
    return mesh;
}

inline std::string read_text(const std::filesystem::path& path)
{
    std::ifstream file(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
}

inline void write_text(const std::filesystem::path& path, const std::string& bytes)
{
    std::ofstream file(path, std::ios::binary);
    file.write(bytes.data(), std::streamsize(bytes.size()));
}

// A fresh directory per test, removed afterwards.
class ScratchDir : public ::testing::Test {
protected:
    void SetUp() override
    {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        std::string name = std::string(info->test_suite_name()) + "_" + info->name();
        for (char& c : name)
            if (c == '/') c = '_';
        dir = std::filesystem::temp_directory_path() /
              ("scalemesh_exporters_" + std::to_string(::getpid()) + "_" + name);
        std::filesystem::remove_all(dir);
        std::filesystem::create_directories(dir);
    }
    void TearDown() override { std::filesystem::remove_all(dir); }

    std::vector<std::string> entries() const
    {
        std::vector<std::string> names;
        for (const auto& entry : std::filesystem::directory_iterator(dir)) names.push_back(entry.path().filename());
        std::sort(names.begin(), names.end());
        return names;
    }

    std::filesystem::path dir;
};

} // namespace scalemesh::test
