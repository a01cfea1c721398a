#include "core/adjacency.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace scalemesh {

VertexTable vertex_triangles(const SurfaceMesh& mesh)
{
    return incident_cells(mesh.triangles, static_cast<int32_t>(mesh.points.size()));
}

VertexTable vertex_neighbours(const SurfaceMesh& mesh)
{
    return vertex_neighbours(mesh, vertex_triangles(mesh));
}

VertexTable vertex_neighbours(const SurfaceMesh& mesh, const VertexTable& fans)
{
    const auto n = static_cast<int32_t>(mesh.points.size());
    VertexTable table;
    table.offsets.resize(n + 1);
    for (int32_t i = 0; i <= n; ++i) table.offsets[i] = 2 * fans.offsets[i];
    // Each row gathers the other two corners of its fan triangles into its
    // own slice of `raw`, then sorts and uniques them (rows in parallel);
    // the rows are compacted after.
    std::vector<int32_t> raw(table.offsets[n]);
    std::vector<int32_t> offsets(n + 1, 0);
    tbb::parallel_for(tbb::blocked_range<int32_t>(0, n, 4096), [&](const tbb::blocked_range<int32_t>& range) {
        for (int32_t i = range.begin(); i != range.end(); ++i) {
            const auto first = raw.begin() + table.offsets[i];
            auto last = first;
            for (const int32_t* f = fans.begin(i); f != fans.end(i); ++f) {
                if (f != fans.begin(i) && *f == f[-1]) continue; // a repeated corner: once is enough
                const Triangle& t = mesh.triangles[*f];
                for (int k = 0; k < 3; ++k)
                    if (t[k] == i) {
                        *last++ = t[(k + 1) % 3];
                        *last++ = t[(k + 2) % 3];
                    }
            }
            std::sort(first, last);
            offsets[i + 1] = static_cast<int32_t>(std::unique(first, last) - first);
        }
    });
    for (int32_t i = 0; i < n; ++i) offsets[i + 1] += offsets[i];
    table.items.resize(offsets[n]);
    tbb::parallel_for(tbb::blocked_range<int32_t>(0, n, 4096), [&](const tbb::blocked_range<int32_t>& range) {
        for (int32_t i = range.begin(); i != range.end(); ++i)
            std::copy_n(raw.begin() + table.offsets[i], offsets[i + 1] - offsets[i], table.items.begin() + offsets[i]);
    });
    table.offsets = std::move(offsets);
    return table;
}

std::vector<std::array<int32_t, 2>> unique_edges(const SurfaceMesh& mesh)
{
    std::vector<std::array<int32_t, 2>> edges;
    edges.reserve(mesh.triangles.size() * 3);
    for (const Triangle& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) {
            int32_t a = t[k], b = t[(k + 1) % 3];
            if (a > b) std::swap(a, b);
            edges.push_back({a, b});
        }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    return edges;
}

EdgeSet edge_set(const std::vector<Triangle>& triangles)
{
    EdgeSet edges;
    edges.reserve(triangles.size() * 3 / 2 + 1);
    for (const Triangle& t : triangles)
        for (int k = 0; k < 3; ++k) edges.insert(edge_key(t[k], t[(k + 1) % 3]));
    return edges;
}

} // namespace scalemesh
