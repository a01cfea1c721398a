#pragma once
// Adjacency of a SurfaceMesh built on demand, in compressed-row form.

#include "core/surface_mesh.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <unordered_set>
#include <vector>

namespace scalemesh {

// Row i lists the items attached to vertex i: items[offsets[i] .. offsets[i+1]).
struct VertexTable {
    std::vector<int32_t> offsets;
    std::vector<int32_t> items;

    int32_t size(int32_t i) const { return offsets[i + 1] - offsets[i]; }
    const int32_t* begin(int32_t i) const { return items.data() + offsets[i]; }
    const int32_t* end(int32_t i) const { return items.data() + offsets[i + 1]; }
};

// The cells (triangles, tets: arrays of point ids) at each of the points
// 0 .. rows - 1, each row in increasing cell order; points from `rows` on
// are left out. One counting pass, then one filling pass.
template <class Cell>
VertexTable incident_cells(const std::vector<Cell>& cells, int32_t rows)
{
    VertexTable table;
    std::vector<int64_t> counts(static_cast<size_t>(rows) + 1, 0);
    for (const Cell& cell : cells)
        for (int32_t v : cell)
            if (v < rows) ++counts[v + 1];
    for (int32_t v = 0; v < rows; ++v) counts[v + 1] += counts[v];
    if (counts[rows] > std::numeric_limits<int32_t>::max())
        throw std::length_error("incident_cells: more than 2^31 cell corners");
    table.offsets.assign(counts.begin(), counts.end());
    table.items.resize(table.offsets[rows]);
    std::vector<int32_t> fill(table.offsets.begin(), table.offsets.end() - 1);
    for (size_t c = 0; c < cells.size(); ++c)
        for (int32_t v : cells[c])
            if (v < rows) table.items[fill[v]++] = static_cast<int32_t>(c);
    return table;
}

// Triangles incident to each vertex.
VertexTable vertex_triangles(const SurfaceMesh& mesh);

// Vertices joined to each vertex by an edge, sorted, without repeats. The
// second form takes the mesh's vertex_triangles.
VertexTable vertex_neighbours(const SurfaceMesh& mesh);
VertexTable vertex_neighbours(const SurfaceMesh& mesh, const VertexTable& fans);

// Undirected edges (a < b), sorted, without repeats.
std::vector<std::array<int32_t, 2>> unique_edges(const SurfaceMesh& mesh);

// The edge u -> v as one key, for hash maps of edges.
inline uint64_t directed_edge_key(int32_t u, int32_t v)
{
    return (static_cast<uint64_t>(static_cast<uint32_t>(u)) << 32) | static_cast<uint32_t>(v);
}

// The edge {u, v} as one key, whichever way it is given.
inline uint64_t edge_key(int32_t u, int32_t v) { return directed_edge_key(std::min(u, v), std::max(u, v)); }

// Undirected edges as edge_key values.
using EdgeSet = std::unordered_set<uint64_t>;

// The edges of `triangles`.
EdgeSet edge_set(const std::vector<Triangle>& triangles);

} // namespace scalemesh
