#include "isosurface/marching_cubes.h"

#include "core/errors.h"
#include "isosurface/cube_table.h"

#include <openvdb/tree/LeafManager.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <memory>
#include <unordered_map>

namespace scalemesh {

bool is_level_set(const openvdb::GridBase& grid) { return grid.getGridClass() == openvdb::GRID_LEVEL_SET; }

namespace {

using openvdb::Coord;
using MaskTree = openvdb::BoolTree;
using MaskLeaf = MaskTree::LeafNodeType;

constexpr int kLeafDim = MaskLeaf::DIM; // 8

// Inside-ness as a positive number: f > 0 inside, f <= 0 outside.
struct Inside {
    bool level_set;
    float iso;
    float operator()(float value) const { return level_set ? iso - value : value - iso; }
};

// Mask of inside voxels, every tile expanded into leaves, so that each
// inside voxel lies in exactly one leaf of the mask.
MaskTree::Ptr inside_mask(const openvdb::FloatTree& tree, const Inside& inside)
{
    auto mask = std::make_shared<MaskTree>(false);

    // Voxels of the input's leaves, in parallel; the leaves are added after.
    openvdb::tree::LeafManager<const openvdb::FloatTree> leaves(tree);
    std::vector<std::unique_ptr<MaskLeaf>> built(leaves.leafCount());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.leafCount()), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const auto& leaf = leaves.leaf(i);
            std::unique_ptr<MaskLeaf> out;
            for (openvdb::Index n = 0; n < MaskLeaf::SIZE; ++n)
                if (inside(leaf.getValue(n)) > 0) {
                    if (!out) out = std::make_unique<MaskLeaf>(leaf.origin(), false);
                    out->setValueOn(n, true);
                }
            built[i] = std::move(out);
        }
    });
    for (auto& leaf : built)
        if (leaf) mask->addLeaf(leaf.release());

    // Tiles (active or not) whose value is inside.
    auto it = tree.cbeginValueAll();
    it.setMaxDepth(openvdb::FloatTree::ValueAllCIter::LEAF_DEPTH - 1);
    for (; it; ++it) {
        if (it.getDepth() == openvdb::FloatTree::ValueAllCIter::LEAF_DEPTH) continue;
        if (inside(*it) <= 0) continue;
        if (it.getDepth() == 0)
            throw InputError("the grid has an inside tile at its root level (an inside region of 4096^3 voxels)",
                             "resample the image to fewer voxels or crop it to the region of interest");
        openvdb::CoordBBox box;
        it.getBoundingBox(box);
        mask->fill(box, true, true);
    }
    mask->voxelizeActiveTiles();
    return mask;
}

// Where each crossing lattice edge's vertex lives. A crossing edge has one
// inside end; the vertex belongs to that voxel, found as
// base[voxel] + (rank of the edge's direction among the voxel's crossings).
struct LeafVertices {
    std::array<int32_t, MaskLeaf::SIZE> base{};
    std::array<uint8_t, MaskLeaf::SIZE> directions{}; // bit d: crossing toward neighbour d
    int32_t count = 0;
};

// The six lattice directions: +x -x +y -y +z -z.
constexpr int kDir[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

// Dense copy of f over the leaf and a one-voxel rim on each side.
struct Block {
    static constexpr int N = kLeafDim + 2; // covers [origin - 1, origin + 8]
    std::array<float, N * N * N> f;
    Coord origin; // of the leaf
    float& at(int i, int j, int k) { return f[((i + 1) * N + (j + 1)) * N + (k + 1)]; }
    float at(int i, int j, int k) const { return f[((i + 1) * N + (j + 1)) * N + (k + 1)]; }
};

void fill_block(Block& block, const Coord& origin, openvdb::tree::ValueAccessor<const openvdb::FloatTree>& acc, const Inside& inside)
{
    block.origin = origin;
    const auto* leaf = acc.probeConstLeaf(origin);
    for (int i = -1; i <= kLeafDim; ++i)
        for (int j = -1; j <= kLeafDim; ++j)
            for (int k = -1; k <= kLeafDim; ++k) {
                const bool in_leaf = i >= 0 && j >= 0 && k >= 0 && i < kLeafDim && j < kLeafDim && k < kLeafDim;
                const Coord c = origin.offsetBy(i, j, k);
                const float value = (in_leaf && leaf) ? leaf->getValue(c) : acc.getValue(c);
                block.at(i, j, k) = inside(value);
            }
}

bool leaf_and_neighbours_full(const MaskTree& mask, const MaskLeaf& leaf)
{
    if (!leaf.getValueMask().isOn()) return false;
    for (int i = -1; i <= 1; ++i)
        for (int j = -1; j <= 1; ++j)
            for (int k = -1; k <= 1; ++k) {
                if (!i && !j && !k) continue;
                const MaskLeaf* n = mask.probeConstLeaf(leaf.origin().offsetBy(i * kLeafDim, j * kLeafDim, k * kLeafDim));
                if (!n || !n->getValueMask().isOn()) return false;
            }
    return true;
}

struct CoordHash {
    size_t operator()(const Coord& c) const { return c.hash<20>(); }
};

} // namespace

SurfaceMesh marching_cubes(const openvdb::FloatGrid& grid, const IsosurfaceParams& params)
{
    const bool level_set = is_level_set(grid);
    const Inside inside{level_set, static_cast<float>(params.iso.value_or(level_set ? 0.0 : 0.5))};
    if (!std::isfinite(inside.iso))
        throw InputError("the iso value is not finite", "give a finite --iso");
    if (inside(grid.background()) > 0)
        throw InputError("the grid's background value " + std::to_string(grid.background()) +
                             " is inside at iso value " + std::to_string(inside.iso) + ", so the surface is not bounded",
                         level_set ? "for a level set choose an iso value below the background (the narrow-band width)"
                                   : "for a label or fog grid choose an iso value above the background");

    const MaskTree::Ptr mask = inside_mask(grid.tree(), inside);
    openvdb::tree::LeafManager<const MaskTree> mask_leaves(*mask);
    const size_t leaf_count = mask_leaves.leafCount();
    if (leaf_count == 0)
        throw InputError("no voxel is inside at iso value " + std::to_string(inside.iso) + ", so there is no surface",
                         "check the iso value (--iso) or the label, and that the grid is not empty");

    std::unordered_map<Coord, int32_t, CoordHash> leaf_index;
    leaf_index.reserve(leaf_count * 2);
    for (size_t i = 0; i < leaf_count; ++i) leaf_index.emplace(mask_leaves.leaf(i).origin(), static_cast<int32_t>(i));

    // Pass 1: vertices on the crossing edges, owned by their inside voxel.
    std::vector<std::unique_ptr<LeafVertices>> vertices(leaf_count);
    std::vector<std::vector<openvdb::Vec3d>> positions(leaf_count);
    std::vector<char> skip(leaf_count, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaf_count), [&](const tbb::blocked_range<size_t>& r) {
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(grid.tree());
        Block block;
        for (size_t li = r.begin(); li != r.end(); ++li) {
            const MaskLeaf& leaf = mask_leaves.leaf(li);
            if (leaf_and_neighbours_full(*mask, leaf)) {
                skip[li] = 1;
                continue;
            }
            fill_block(block, leaf.origin(), acc, inside);
            auto table = std::make_unique<LeafVertices>();
            std::vector<openvdb::Vec3d>& pos = positions[li];
            for (auto it = leaf.cbeginValueOn(); it; ++it) {
                const openvdb::Index n = it.pos();
                const Coord local = MaskLeaf::offsetToLocalCoord(n);
                const float f0 = block.at(local.x(), local.y(), local.z());
                table->base[n] = static_cast<int32_t>(pos.size());
                for (int d = 0; d < 6; ++d) {
                    const float f1 = block.at(local.x() + kDir[d][0], local.y() + kDir[d][1], local.z() + kDir[d][2]);
                    if (f1 > 0) continue;
                    table->directions[n] |= uint8_t(1u << d);
                    // Linear interpolation of the zero of f; f0 > 0 >= f1.
                    const double t = static_cast<double>(f0) / (static_cast<double>(f0) - static_cast<double>(f1));
                    const Coord c = it.getCoord();
                    pos.push_back(grid.indexToWorld(openvdb::Vec3d(c.x() + t * kDir[d][0], c.y() + t * kDir[d][1],
                                                                   c.z() + t * kDir[d][2])));
                }
            }
            table->count = static_cast<int32_t>(pos.size());
            if (table->count > 0) vertices[li] = std::move(table);
        }
    });

    std::vector<int32_t> first_vertex(leaf_count + 1, 0);
    for (size_t i = 0; i < leaf_count; ++i)
        first_vertex[i + 1] = first_vertex[i] + (vertices[i] ? vertices[i]->count : 0);

    // Pass 2: triangles of each cube, owned by the leaf holding its first
    // inside corner, so every cube is triangulated exactly once.
    const auto& table = mc::cube_table(params.connectivity);
    std::vector<std::vector<Triangle>> triangles(leaf_count);
    std::vector<std::vector<openvdb::Vec3d>> extra(leaf_count);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaf_count), [&](const tbb::blocked_range<size_t>& r) {
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(grid.tree());
        Block block;
        for (size_t li = r.begin(); li != r.end(); ++li) {
            if (skip[li]) continue;
            const MaskLeaf& leaf = mask_leaves.leaf(li);
            const Coord origin = leaf.origin();
            fill_block(block, origin, acc, inside);

            // Vertex id of the crossing on cube edge e of the cube at local p.
            auto vertex_id = [&](int pi, int pj, int pk, int e) -> int32_t {
                const int a = mc::kEdgeCorners[e][0], b = mc::kEdgeCorners[e][1];
                const int axis = mc::kEdgeAxis[e];
                const bool a_inside = block.at(pi + (a & 1), pj + ((a >> 1) & 1), pk + ((a >> 2) & 1)) > 0;
                const int c = a_inside ? a : b;
                const int d = 2 * axis + (a_inside ? 0 : 1);
                const Coord voxel = origin.offsetBy(pi + (c & 1), pj + ((c >> 1) & 1), pk + ((c >> 2) & 1));
                const Coord voxel_leaf = voxel & ~(kLeafDim - 1);
                size_t owner = li;
                if (voxel_leaf != origin) owner = static_cast<size_t>(leaf_index.at(voxel_leaf));
                const LeafVertices& lv = *vertices[owner];
                const openvdb::Index n = MaskLeaf::coordToOffset(voxel);
                const int rank = std::popcount(static_cast<unsigned>(lv.directions[n] & ((1u << d) - 1)));
                return first_vertex[owner] + lv.base[n] + rank;
            };

            // Position of a vertex by global id; pass 1 is complete.
            auto position = [&](int32_t id) {
                const size_t owner = static_cast<size_t>(
                    std::upper_bound(first_vertex.begin(), first_vertex.end(), id) - first_vertex.begin() - 1);
                return positions[owner][static_cast<size_t>(id - first_vertex[owner])];
            };

            std::vector<Triangle>& out = triangles[li];
            std::vector<openvdb::Vec3d>& centres = extra[li];
            int32_t ids[16];
            for (int i = -1; i < kLeafDim; ++i)
                for (int j = -1; j < kLeafDim; ++j)
                    for (int k = -1; k < kLeafDim; ++k) {
                        int mask_bits = 0;
                        for (int c = 0; c < 8; ++c)
                            if (block.at(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)) > 0) mask_bits |= 1 << c;
                        if (mask_bits == 0 || mask_bits == 0xff) continue;
                        const int first = std::countr_zero(static_cast<unsigned>(mask_bits));
                        const int fi = i + (first & 1), fj = j + ((first >> 1) & 1), fk = k + ((first >> 2) & 1);
                        if (fi < 0 || fj < 0 || fk < 0 || fi >= kLeafDim || fj >= kLeafDim || fk >= kLeafDim) continue;
                        const mc::CubeCase& cube = table[mask_bits];
                        for (int e = 0; e < 12; ++e) ids[e] = -1;
                        for (const auto& t : cube.triangles)
                            for (uint8_t v : t)
                                if (v < 12 && ids[v] < 0) ids[v] = vertex_id(i, j, k, v);
                        // Centre vertices get provisional negative ids, made
                        // global once every leaf's count is known.
                        for (size_t c = 0; c < cube.centre_loops.size(); ++c) {
                            openvdb::Vec3d sum(0.0);
                            for (uint8_t e : cube.centre_loops[c]) sum += position(vertex_id(i, j, k, e));
                            centres.push_back(sum / static_cast<double>(cube.centre_loops[c].size()));
                            ids[12 + c] = -static_cast<int32_t>(centres.size());
                        }
                        for (const auto& t : cube.triangles) out.push_back({ids[t[0]], ids[t[1]], ids[t[2]]});
                    }
        }
    });

    // A mirroring image-to-world transform (negative determinant, as many
    // medical images have) turns the index-space orientation inside out.
    const openvdb::Mat3d linear = grid.transform().baseMap()->getAffineMap()->getMat4().getMat3();
    const bool mirrored = linear.det() < 0;

    SurfaceMesh mesh;
    mesh.points.reserve(first_vertex[leaf_count]);
    for (const auto& pos : positions)
        for (const auto& p : pos) mesh.points.push_back({p.x(), p.y(), p.z()});
    for (size_t li = 0; li < leaf_count; ++li) {
        const auto base = static_cast<int32_t>(mesh.points.size());
        for (const auto& p : extra[li]) mesh.points.push_back({p.x(), p.y(), p.z()});
        for (Triangle& t : triangles[li])
            for (int32_t& v : t)
                if (v < 0) v = base - v - 1;
    }
    size_t triangle_count = 0;
    for (const auto& t : triangles) triangle_count += t.size();
    mesh.triangles.reserve(triangle_count);
    for (const auto& t : triangles) mesh.triangles.insert(mesh.triangles.end(), t.begin(), t.end());
    if (mirrored)
        for (Triangle& t : mesh.triangles) std::swap(t[1], t[2]);
    return mesh;
}

} // namespace scalemesh
