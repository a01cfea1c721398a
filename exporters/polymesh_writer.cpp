#include "exporters/polymesh_writer.h"

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/face_measures.h"
#include "core/vec3.h"
#include "exporters/foam_file.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <string_view>

namespace scalemesh {

namespace {

// The files are cut into blocks fixed by the mesh alone (so many cells, faces
// or points each), formatted in parallel and written in order: the bytes do
// not depend on the number of threads, and no file is ever held whole.
constexpr size_t kCellsPerBlock = 16384; // and their internal faces, about 2 per cell
constexpr size_t kItemsPerBlock = 32768; // boundary faces, points or face offsets

// A growing byte buffer that numbers are formatted straight into.
class Text {
public:
    // Room for `n` more bytes at the returned pointer; `commit` says how many were used.
    char* room(size_t n)
    {
        if (size_ + n > capacity_) grow(size_ + n);
        return data_.get() + size_;
    }
    void commit(char* end) { size_ = static_cast<size_t>(end - data_.get()); }

    void append(std::string_view s) { commit(std::copy(s.begin(), s.end(), room(s.size()))); }
    void bytes(const void* p, size_t n)
    {
        char* at = room(n);
        std::memcpy(at, p, n);
        size_ += n;
    }
    template <typename Number>
    void number(Number value, char after)
    {
        char* at = room(40);
        at = std::to_chars(at, at + 39, value).ptr;
        *at++ = after;
        commit(at);
    }

    void clear() { size_ = 0; }
    std::string_view view() const { return {data_.get(), size_}; }

private:
    void grow(size_t needed)
    {
        const size_t capacity = std::max(needed, 2 * capacity_ + 4096);
        std::unique_ptr<char[]> data(new char[capacity]);
        if (size_ > 0) std::memcpy(data.get(), data_.get(), size_);
        data_ = std::move(data);
        capacity_ = capacity;
    }

    std::unique_ptr<char[]> data_;
    size_t size_ = 0, capacity_ = 0;
};

// One polyMesh file: its header and the small text around its lists.
class FoamFile {
public:
    FoamFile(const std::filesystem::path& path, StagedOutputs& outputs, bool binary)
        : out_(path, outputs), binary_(binary)
    {
    }

    void header(const std::string& cls, const std::string& object, const std::string& note = "")
    {
        text(foam_file_header(binary_, cls, "constant/polyMesh", object, note));
    }

    void text(std::string_view s) { out_.text(s); }

    // The opening of a list of n entries: "n\n(" and, in ASCII, a newline.
    void open_list(size_t n)
    {
        char digits[24];
        text(std::string_view(digits, static_cast<size_t>(std::to_chars(digits, digits + sizeof digits, n).ptr - digits)));
        text(binary_ ? "\n(" : "\n(\n");
    }
    void close_list() { text(")\n"); }

    void finish() { out_.finish(); }

private:
    FoamFileOutput out_;
    bool binary_;
};

// Formats blocks 0 .. count - 1 in parallel, format(block, texts) filling one
// text per file, and appends the texts to `files` in block order, through a
// bounded set of buffers: the files are never held whole.
template <size_t Files, typename Format>
void stream_blocks(size_t count, const std::array<FoamFile*, Files>& files, const Format& format)
{
    if (count == 0) return;
    struct Job {
        size_t block = 0;
        std::array<Text, Files> texts;
    };
    const size_t tokens = 2 * static_cast<size_t>(tbb::this_task_arena::max_concurrency()) + 2;
    std::vector<std::unique_ptr<Job>> free;
    std::mutex free_mutex;
    size_t next = 0;
    tbb::parallel_pipeline(
        tokens,
        tbb::make_filter<void, Job*>(tbb::filter_mode::serial_in_order,
                                     [&](tbb::flow_control& control) -> Job* {
                                         if (next == count) {
                                             control.stop();
                                             return nullptr;
                                         }
                                         std::unique_ptr<Job> job;
                                         {
                                             std::lock_guard lock(free_mutex);
                                             if (!free.empty()) {
                                                 job = std::move(free.back());
                                                 free.pop_back();
                                             }
                                         }
                                         if (!job) job = std::make_unique<Job>();
                                         job->block = next++;
                                         return job.release();
                                     }) &
            tbb::make_filter<Job*, Job*>(tbb::filter_mode::parallel,
                                         [&](Job* job) {
                                             for (Text& t : job->texts) t.clear();
                                             format(job->block, job->texts);
                                             return job;
                                         }) &
            tbb::make_filter<Job*, void>(tbb::filter_mode::serial_in_order, [&](Job* raw) {
                std::unique_ptr<Job> job(raw);
                for (size_t f = 0; f < Files; ++f) files[f]->text(job->texts[f].view());
                std::lock_guard lock(free_mutex);
                free.push_back(std::move(job));
            }));
}

// Labels in an OpenFOAM list: raw 32-bit in binary, one per line in ASCII.
void put_label(Text& out, int32_t value, bool binary)
{
    if (binary) out.bytes(&value, sizeof value);
    else out.number(value, '\n');
}

// The faces of the mesh in polyMesh order, without holding them: the internal
// faces are generated from the cells block by block, the boundary faces are
// kept as their slots 4 t + k (a few per cent of the faces).
class FaceOrder {
public:
    FaceOrder(const TetMesh& mesh, const TetFaceAdjacency& adjacency) : mesh_(mesh), adjacency_(adjacency) {}

    size_t cell_blocks() const { return (mesh_.tets.size() + kCellsPerBlock - 1) / kCellsPerBlock; }
    size_t boundary_blocks() const { return (boundary.size() + kItemsPerBlock - 1) / kItemsPerBlock; }

    // Each cell owns the faces it shares with higher cells, taken in the order
    // of those neighbours: upper-triangular order without sorting the faces.
    // Its outward orientation points to the neighbour. visit(owner,
    // neighbour, points) for each internal face of the cells of `block`.
    template <typename Visit>
    void internal_faces(size_t block, const Visit& visit) const
    {
        const size_t last = std::min(mesh_.tets.size(), (block + 1) * kCellsPerBlock);
        for (size_t t = block * kCellsPerBlock; t < last; ++t) {
            int32_t across[4], face[4];
            int n = 0;
            for (int k = 0; k < 4; ++k) {
                const int32_t other = adjacency_.across[4 * t + k];
                if (other <= static_cast<int32_t>(t)) continue;
                // Insertion by neighbour; equal neighbours (only in a mesh of
                // two copies of one tet) keep the order of k.
                int i = n++;
                for (; i > 0 && across[i - 1] > other; --i) {
                    across[i] = across[i - 1];
                    face[i] = face[i - 1];
                }
                across[i] = other;
                face[i] = k;
            }
            for (int i = 0; i < n; ++i) visit(static_cast<int32_t>(t), across[i], tet_face(mesh_.tets[t], face[i]));
        }
    }

    // visit(owner, points) for the boundary faces of `block`.
    template <typename Visit>
    void boundary_faces(size_t block, const Visit& visit) const
    {
        const size_t last = std::min(boundary.size(), (block + 1) * kItemsPerBlock);
        for (size_t i = block * kItemsPerBlock; i < last; ++i) {
            const int32_t slot = boundary[i];
            visit(slot / 4, tet_face(mesh_.tets[slot / 4], slot % 4));
        }
    }

    // visit(owner, neighbour or -1, points) for the faces of block b of
    // cell_blocks() + boundary_blocks(): the whole face list in order.
    template <typename Visit>
    void faces(size_t b, const Visit& visit) const
    {
        if (b < cell_blocks()) {
            internal_faces(b, visit);
        } else {
            boundary_faces(b - cell_blocks(), [&](int32_t owner, const Triangle& points) { visit(owner, -1, points); });
        }
    }
    size_t face_blocks() const { return cell_blocks() + boundary_blocks(); }

    int64_t internal_count = 0;
    std::vector<int32_t> boundary; // slots 4 t + k, grouped by patch, in cell order within a patch
    std::vector<int64_t> patch_faces;

private:
    const TetMesh& mesh_;
    const TetFaceAdjacency& adjacency_;
};

// Rotates a triangle so that its smallest index comes first (same orientation).
Triangle canonical(Triangle t)
{
    while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
    return t;
}

std::string patch_name(const TetMesh& mesh, int32_t patch)
{
    if (patch < static_cast<int32_t>(mesh.patch_names.size())) return mesh.patch_names[patch];
    return patch == 0 ? "wall" : "patch_" + std::to_string(patch);
}

// Validates the mesh (nothing the next tool would choke on is written) and
// lays out its faces: the count of internal faces, the boundary faces by
// patch. One parallel pass over the cells does both.
FaceOrder lay_out_faces(const TetMesh& mesh, const TetFaceAdjacency& adjacency)
{
    if (adjacency.across.size() != 4 * mesh.tets.size())
        throw std::invalid_argument("the face adjacency is not that of this mesh (" +
                                    std::to_string(adjacency.across.size()) + " faces for " +
                                    std::to_string(mesh.tets.size()) + " tets)");
    if (!mesh.boundary_patch.empty() && mesh.boundary_patch.size() != mesh.boundary_faces.size())
        throw StageError("polyMesh export", "boundary_patch does not have one entry per boundary face");

    // The patch of each boundary face by the face as written (smallest point
    // first, orientation kept): an open face of a cell must find itself here.
    struct Keyed {
        Triangle face;
        int32_t patch;
        bool operator<(const Keyed& o) const { return face < o.face; }
    };
    std::vector<Keyed> patch_of(mesh.boundary_faces.size());
    int32_t patch_count = 1;
    for (size_t f = 0; f < mesh.boundary_faces.size(); ++f) {
        const int32_t patch = mesh.boundary_patch.empty() ? 0 : mesh.boundary_patch[f];
        if (patch < 0) throw StageError("polyMesh export", "boundary face " + std::to_string(f) + " has a negative patch id");
        patch_count = std::max(patch_count, patch + 1);
        patch_of[f] = {canonical(mesh.boundary_faces[f]), patch};
    }
    tbb::parallel_sort(patch_of.begin(), patch_of.end());
    bool repeated = false;
    for (size_t f = 1; f < patch_of.size(); ++f) repeated = repeated || !(patch_of[f - 1] < patch_of[f]);

    FaceOrder order(mesh, adjacency);
    struct Block {
        int64_t internal = 0, nonpositive = 0, unmatched = 0;
        std::vector<std::pair<int32_t, int32_t>> boundary; // (patch, slot)
    };
    std::vector<Block> blocks(order.cell_blocks());
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        Block& block = blocks[b];
        const size_t last = std::min(mesh.tets.size(), (b + 1) * kCellsPerBlock);
        for (size_t t = b * kCellsPerBlock; t < last; ++t) {
            const Tet& tet = mesh.tets[t];
            if (!(tet_volume6(mesh.points[tet[0]], mesh.points[tet[1]], mesh.points[tet[2]], mesh.points[tet[3]]) > 0))
                ++block.nonpositive;
            for (int k = 0; k < 4; ++k) {
                const int32_t across = adjacency.across[4 * t + k];
                if (across > static_cast<int32_t>(t)) {
                    ++block.internal;
                } else if (across == TetFaceAdjacency::kBoundary) {
                    const Keyed key{canonical(tet_face(tet, k)), 0};
                    const auto it = std::lower_bound(patch_of.begin(), patch_of.end(), key);
                    if (it == patch_of.end() || it->face != key.face) ++block.unmatched;
                    else block.boundary.emplace_back(it->patch, static_cast<int32_t>(4 * t + k));
                }
            }
        }
    });
    int64_t nonpositive = 0, unmatched = 0, open = 0;
    order.patch_faces.assign(patch_count, 0);
    for (const Block& block : blocks) {
        order.internal_count += block.internal;
        nonpositive += block.nonpositive;
        unmatched += block.unmatched;
        open += block.unmatched + static_cast<int64_t>(block.boundary.size());
        for (const auto& [patch, slot] : block.boundary) ++order.patch_faces[patch];
    }
    if (nonpositive > 0)
        throw StageError("polyMesh export", std::to_string(nonpositive) + " tets have zero or negative volume (inverted cells)");
    if (adjacency.overshared_faces > 0)
        throw StageError("polyMesh export", std::to_string(adjacency.overshared_faces) +
                                                " faces are shared by more than two tets");
    // Open faces are distinct, so they are exactly the boundary faces when
    // each finds one, the boundary faces are distinct, and the counts agree.
    if (unmatched > 0 || repeated || open != static_cast<int64_t>(mesh.boundary_faces.size()))
        throw StageError("polyMesh export", "the mesh's open faces (" + std::to_string(open) +
                                                ") are not exactly its boundary faces (" +
                                                std::to_string(mesh.boundary_faces.size()) + "), same orientation");

    // Grouped by patch, in cell order within each patch.
    std::vector<int64_t> cursor(patch_count, 0);
    for (int32_t p = 1; p < patch_count; ++p) cursor[p] = cursor[p - 1] + order.patch_faces[p - 1];
    order.boundary.resize(static_cast<size_t>(open));
    for (const Block& block : blocks)
        for (const auto& [patch, slot] : block.boundary) order.boundary[cursor[patch]++] = slot;
    return order;
}

// The faces of a mesh whose cells are groups of tets, held as lists: the
// internal faces between different cells, in upper-triangular order, then
// the boundary faces of `order` with their cells as owners.
struct GroupedFaces {
    std::vector<int32_t> owner, neighbour, offsets{0}, points;
    int64_t quads = 0;

    size_t blocks() const { return (owner.size() + kItemsPerBlock - 1) / kItemsPerBlock; }
    // visit(owner, neighbour or -1, points, count) for the faces of block b.
    template <typename Visit>
    void faces(size_t b, const Visit& visit) const
    {
        const size_t last = std::min(owner.size(), (b + 1) * kItemsPerBlock);
        for (size_t f = b * kItemsPerBlock; f < last; ++f)
            visit(owner[f], f < neighbour.size() ? neighbour[f] : -1, points.data() + offsets[f],
                  offsets[f + 1] - offsets[f]);
    }
    void add(int32_t cell, const int32_t* p, int count)
    {
        owner.push_back(cell);
        points.insert(points.end(), p, p + count);
        offsets.push_back(static_cast<int32_t>(points.size()));
    }
};

Vec3 triangle_normal(const TetMesh& mesh, const Triangle& t)
{
    return cross(mesh.points[t[1]] - mesh.points[t[0]], mesh.points[t[2]] - mesh.points[t[0]]);
}

// The internal faces of GroupedFaces below, no boundary faces yet.
GroupedFaces group_internal_faces(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                  const std::vector<int32_t>& cell_of_tet, int32_t cells,
                                  const std::vector<char>* quad_cells)
{
    if (quad_cells && quad_cells->size() != static_cast<size_t>(std::max(cells, 0)))
        throw std::invalid_argument("quad_cells has " + std::to_string(quad_cells->size()) + " entries for " +
                                    std::to_string(cells) + " cells");
    if (cell_of_tet.size() != mesh.tets.size())
        throw std::invalid_argument("cell_of_tet has " + std::to_string(cell_of_tet.size()) + " entries for " +
                                    std::to_string(mesh.tets.size()) + " tets");
    std::vector<int32_t> size(static_cast<size_t>(std::max(cells, 0)), 0);
    for (int32_t c : cell_of_tet) {
        if (c < 0 || c >= cells) throw std::invalid_argument("cell_of_tet names cell " + std::to_string(c) +
                                                             " outside 0 .. " + std::to_string(cells - 1));
        ++size[c];
    }
    if (std::find(size.begin(), size.end(), 0) != size.end())
        throw std::invalid_argument("cell_of_tet leaves a cell without tets");

    // Each internal triangle once, oriented from its owner (the lower cell).
    struct Internal {
        int32_t owner, neighbour;
        Triangle points;
        bool operator<(const Internal& o) const
        {
            return owner != o.owner ? owner < o.owner : neighbour != o.neighbour ? neighbour < o.neighbour : points < o.points;
        }
    };
    std::vector<Internal> internal;
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        for (int k = 0; k < 4; ++k) {
            const int32_t across = adjacency.across[4 * t + k];
            if (across <= static_cast<int32_t>(t)) continue;
            const int32_t a = cell_of_tet[t], b = cell_of_tet[across];
            if (a == b) continue;
            Triangle f = tet_face(mesh.tets[t], k); // outward of tet t, so of cell a
            if (a > b) std::swap(f[1], f[2]);
            internal.push_back({std::min(a, b), std::max(a, b), canonical(f)});
        }
    tbb::parallel_sort(internal.begin(), internal.end());

    GroupedFaces out;
    for (size_t i = 0; i < internal.size();) {
        size_t j = i + 1;
        while (j < internal.size() && internal[j].owner == internal[i].owner &&
               internal[j].neighbour == internal[i].neighbour)
            ++j;
        const Internal& first = internal[i];
        bool quad = false;
        const auto joins = [&](int32_t c) { return size[c] == 3 && (!quad_cells || (*quad_cells)[c]); };
        if (j - i == 2 && joins(first.owner) && joins(first.neighbour)) {
            // (u, s, r) and a second triangle on the edge (s, r), taken the
            // other way round: (v, r, s). The quad is u s v r.
            const Triangle& p = first.points;
            const Triangle& q = internal[i + 1].points;
            for (int e = 0; e < 3 && !quad; ++e) {
                const int32_t u = p[e], s = p[(e + 1) % 3], r = p[(e + 2) % 3];
                for (int g = 0; g < 3 && !quad; ++g) {
                    if (q[(g + 1) % 3] != r || q[(g + 2) % 3] != s) continue;
                    const Vec3 n0 = triangle_normal(mesh, p), n1 = triangle_normal(mesh, q);
                    if (!(dot(n0, n1) > 0.7 * norm(n0) * norm(n1))) continue;
                    const int32_t four[4] = {u, s, q[g], r};
                    out.add(first.owner, four, 4);
                    out.neighbour.push_back(first.neighbour);
                    ++out.quads;
                    quad = true;
                }
            }
        }
        if (!quad)
            for (size_t f = i; f < j; ++f) {
                out.add(internal[f].owner, internal[f].points.data(), 3);
                out.neighbour.push_back(internal[f].neighbour);
            }
        i = j;
    }
    return out;
}

GroupedFaces group_faces(const TetMesh& mesh, const TetFaceAdjacency& adjacency, const FaceOrder& order,
                         const std::vector<int32_t>& cell_of_tet, int32_t cells, const std::vector<char>* quad_cells)
{
    GroupedFaces out = group_internal_faces(mesh, adjacency, cell_of_tet, cells, quad_cells);
    for (size_t b = 0; b < order.boundary_blocks(); ++b)
        order.boundary_faces(b, [&](int32_t tet, const Triangle& points) { out.add(cell_of_tet[tet], points.data(), 3); });
    return out;
}

// A face's centre and area vector as OpenFOAM computes them
// (primitiveMeshFaceCentresAndAreas): a triangle's own; a polygon's from the
// fan of triangles on the mean of its points, centres weighted by area.
struct FaceGeometry {
    Vec3 centre, area;
};

FaceGeometry openfoam_face(const TetMesh& mesh, const int32_t* p, int count)
{
    if (count == 3) {
        const Vec3 &a = mesh.points[p[0]], &b = mesh.points[p[1]], &c = mesh.points[p[2]];
        return {(a + b + c) / 3, 0.5 * cross(b - a, c - a)};
    }
    Vec3 mean;
    for (int i = 0; i < count; ++i) mean += mesh.points[p[i]];
    mean /= count;
    Vec3 sum_n, sum_ac;
    double sum_a = 0;
    for (int i = 0; i < count; ++i) {
        const Vec3 &here = mesh.points[p[i]], &next = mesh.points[p[(i + 1) % count]];
        const Vec3 n = cross(next - here, mean - here);
        const double a = norm(n);
        sum_n += n;
        sum_a += a;
        sum_ac += a * (here + next + mean);
    }
    if (!(sum_a > 0)) return {mean, Vec3()};
    return {sum_ac / (3 * sum_a), 0.5 * sum_n};
}

} // namespace

OpenFoamCellChecks openfoam_cell_checks(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                        const std::vector<int32_t>& cell_of_tet, int32_t cells,
                                        const OpenFoamCellBounds& bounds, const std::vector<char>* quad_cells)
{
    const GroupedFaces faces = group_internal_faces(mesh, adjacency, cell_of_tet, cells, quad_cells);
    const size_t internal = faces.neighbour.size();
    // Each face's geometry is computed where it is used, never held: at
    // tens of millions of faces a list of it would cost more than the faces.
    const auto internal_face = [&](size_t f) {
        return openfoam_face(mesh, faces.points.data() + faces.offsets[f], faces.offsets[f + 1] - faces.offsets[f]);
    };
    // visit(cell, geometry, +1 for its owner, -1 for its neighbour, the
    // face's points, their count, the face's other cell or -1) over every
    // face of every cell: the internal faces, then the open faces of the
    // tets (outward).
    const auto each_face = [&](const auto& visit) {
        for (size_t f = 0; f < internal; ++f) {
            const FaceGeometry g = internal_face(f);
            const int32_t* p = faces.points.data() + faces.offsets[f];
            const int count = static_cast<int>(faces.offsets[f + 1] - faces.offsets[f]);
            visit(faces.owner[f], g, 1.0, p, count, faces.neighbour[f]);
            visit(faces.neighbour[f], g, -1.0, p, count, faces.owner[f]);
        }
        for (size_t t = 0; t < mesh.tets.size(); ++t)
            for (int k = 0; k < 4; ++k)
                if (adjacency.across[4 * t + k] < 0) {
                    const Triangle f = tet_face(mesh.tets[t], k);
                    visit(cell_of_tet[t], openfoam_face(mesh, f.data(), 3), 1.0, f.data(), 3, -1);
                }
    };
    // Cell centres (primitiveMeshCellCentresAndVols): the mean of the face
    // centres as apex, then the pyramids on the faces, their centroids
    // weighted by volume.
    std::vector<Vec3> estimate(cells), centre(cells);
    {
        std::vector<int32_t> count(cells, 0);
        each_face([&](int32_t c, const FaceGeometry& g, double, const int32_t*, int, int32_t) {
            estimate[c] += g.centre, ++count[c];
        });
        for (int32_t c = 0; c < cells; ++c) estimate[c] /= std::max(count[c], 1);
    }
    {
        std::vector<double> volume(cells, 0.0);
        each_face([&](int32_t c, const FaceGeometry& g, double side, const int32_t*, int, int32_t) {
            const double pyramid = side * dot(g.area, g.centre - estimate[c]);
            centre[c] += pyramid * (0.75 * g.centre + 0.25 * estimate[c]);
            volume[c] += pyramid;
        });
        for (int32_t c = 0; c < cells; ++c) centre[c] = volume[c] != 0 ? centre[c] / volume[c] : estimate[c];
    }

    std::vector<int32_t> tets_in(cells, 0);
    for (int32_t c : cell_of_tet) ++tets_in[c];
    OpenFoamCellChecks out;
    out.min_pyramid_height = std::numeric_limits<double>::infinity();
    out.min_weight = internal > 0 ? 1.0 : 0.0;
    // A face beyond a bound: its cells of several tets are split back.
    const auto fail = [&](int32_t a, int32_t b) {
        for (int32_t c : {a, b})
            if (c >= 0 && tets_in[c] > 1) out.grouped_cells_failing.push_back(c);
    };
    // Skewness (faceSkewness, boundaryFaceSkewness): the face centre's
    // offset from where the join d of the cell centres crosses the face,
    // over the face's extent in that direction (at least 0.2 |d|; on the
    // boundary, d from the cell centre to the face, at least 0.4 |d|).
    const auto skewness = [&](const FaceGeometry& g, const int32_t* p, int count, const Vec3& from, const Vec3& d,
                              double least) {
        const Vec3 to_face = g.centre - from;
        const Vec3 sv = to_face - (dot(g.area, to_face) / (dot(g.area, d) + 1e-300)) * d;
        const Vec3 sv_hat = sv / (norm(sv) + 1e-300);
        double extent = least * norm(d) + 1e-300;
        for (int i = 0; i < count; ++i) extent = std::max(extent, std::abs(dot(sv_hat, mesh.points[p[i]] - g.centre)));
        return norm(sv) / extent;
    };
    // Face pyramids (facePyramidVolume) and skewness, face by face, from
    // the owner's side; non-orthogonality on the internal faces.
    each_face([&](int32_t c, const FaceGeometry& g, double side, const int32_t* p, int count, int32_t other) {
        const double area = norm(g.area);
        const double height = side * dot(g.area, g.centre - centre[c]) / (area + 1e-300);
        const double relative = height / (std::sqrt(area) + 1e-300);
        out.min_pyramid_height = std::min(out.min_pyramid_height, relative);
        if (!(relative > bounds.pyramid_height)) ++out.flat_pyramids, fail(c, other);
        if (!(height > 0)) ++out.checkmesh_failures;
        if (side < 0) return; // the rest once per face
        double skew;
        if (other >= 0) {
            const Vec3 d = centre[other] - centre[c];
            // A flat face or a zero join: 90 degrees, beyond any bound.
            const double cosine = std::min(1.0, face_orthogonality_cosine(g.area, d, 0.0));
            const double angle = std::acos(std::max(-1.0, cosine)) * 180 / 3.14159265358979323846;
            out.max_non_orthogonality_deg = std::max(out.max_non_orthogonality_deg, angle);
            if (!(angle <= bounds.non_orthogonality_deg)) ++out.faces_beyond_orthogonality, fail(c, other);
            const double weight = face_interpolation_weight(g.area, g.centre, centre[c], centre[other]);
            out.min_weight = std::min(out.min_weight, weight);
            if (!(weight >= bounds.weight)) ++out.light_faces, fail(c, other);
            skew = skewness(g, p, count, centre[c], d, 0.2);
        } else {
            const Vec3 normal = g.area / (area + 1e-300);
            // d reaches the face only, half the way to a mirrored cell.
            skew = skewness(g, p, count, centre[c], normal * dot(normal, g.centre - centre[c]), 0.4);
        }
        out.max_skewness = std::max(out.max_skewness, skew);
        if (!(skew <= bounds.skewness)) ++out.skew_faces, fail(c, other);
        if (!(skew <= 4)) ++out.checkmesh_failures; // primitiveMesh::skewThreshold_
    });
    if (!std::isfinite(out.min_pyramid_height)) out.min_pyramid_height = 0;
    std::sort(out.grouped_cells_failing.begin(), out.grouped_cells_failing.end());
    out.grouped_cells_failing.erase(std::unique(out.grouped_cells_failing.begin(), out.grouped_cells_failing.end()),
                                    out.grouped_cells_failing.end());
    return out;
}

PolyMeshCounts write_polymesh(const TetMesh& mesh, const std::filesystem::path& case_dir, const PolyMeshOptions& options)
{
    if (mesh.tets.empty()) throw StageError("polyMesh export", "the mesh has no cells");
    if (!(options.scale > 0) || !std::isfinite(options.scale))
        throw StageError("polyMesh export", "the coordinate scale must be a positive number");
    TetFaceAdjacency computed;
    if (!options.adjacency) computed = tet_face_adjacency(mesh);
    const TetFaceAdjacency& adjacency = options.adjacency ? *options.adjacency : computed;
    const FaceOrder order = lay_out_faces(mesh, adjacency);
    const int32_t patch_count = static_cast<int32_t>(order.patch_faces.size());
    std::vector<std::string> types(patch_count);
    for (int32_t p = 0; p < patch_count; ++p) {
        types[p] = p < static_cast<int32_t>(options.patch_types.size()) ? options.patch_types[p] : "wall";
        if (types[p] != "wall" && types[p] != "patch")
            throw StageError("polyMesh export", "patch type '" + types[p] + "' is neither wall nor patch");
    }

    GroupedFaces grouped;
    if (options.cell_of_tet)
        grouped = group_faces(mesh, adjacency, order, *options.cell_of_tet, options.cells, options.quad_cells);

    PolyMeshCounts counts;
    counts.points = static_cast<int64_t>(mesh.points.size());
    counts.cells = options.cell_of_tet ? options.cells : static_cast<int64_t>(mesh.tets.size());
    counts.internal_faces =
        options.cell_of_tet ? static_cast<int64_t>(grouped.neighbour.size()) : order.internal_count;
    counts.faces = counts.internal_faces + static_cast<int64_t>(order.boundary.size());
    counts.patch_faces = order.patch_faces;
    counts.quad_faces = grouped.quads;

    // AtomicOutput makes the directory (and takes it along if the files
    // never come).
    const std::filesystem::path dir = case_dir / "constant" / "polyMesh";

    const bool binary = options.binary;
    StagedOutputs outputs;
    auto open = [&](const char* name) { return FoamFile(dir / name, outputs, binary); };
    std::ostringstream note;
    note << "nPoints:" << counts.points << " nCells:" << counts.cells << " nFaces:" << counts.faces
         << " nInternalFaces:" << counts.internal_faces;
    const size_t n_faces = static_cast<size_t>(counts.faces);

    {
        FoamFile points = open("points");
        points.header("vectorField", "points");
        points.open_list(mesh.points.size());
        const double scale = options.scale;
        stream_blocks<1>((mesh.points.size() + kItemsPerBlock - 1) / kItemsPerBlock, {&points}, [&](size_t b, auto& out) {
            const size_t last = std::min(mesh.points.size(), (b + 1) * kItemsPerBlock);
            for (size_t i = b * kItemsPerBlock; i < last; ++i) {
                const Vec3& p = mesh.points[i];
                const double xyz[3] = {p.x * scale, p.y * scale, p.z * scale};
                if (binary) {
                    out[0].bytes(xyz, sizeof xyz);
                } else {
                    out[0].append("(");
                    out[0].number(xyz[0], ' ');
                    out[0].number(xyz[1], ' ');
                    out[0].number(xyz[2], ')');
                    out[0].append("\n");
                }
            }
        });
        points.close_list();
        points.finish();
    }
    {
        // faces, owner and neighbour from one pass over the faces.
        FoamFile faces = open("faces"), owner = open("owner"), neighbour = open("neighbour");
        faces.header(binary ? "faceCompactList" : "faceList", "faces");
        const bool grouped_cells = options.cell_of_tet != nullptr;
        if (binary) {
            // faceCompactList: the offsets, then the point labels.
            faces.open_list(n_faces + 1);
            stream_blocks<1>(n_faces / kItemsPerBlock + 1, {&faces}, [&](size_t b, auto& out) {
                const size_t last = std::min(n_faces + 1, (b + 1) * kItemsPerBlock);
                for (size_t f = b * kItemsPerBlock; f < last; ++f)
                    put_label(out[0], grouped_cells ? grouped.offsets[f] : static_cast<int32_t>(3 * f), true);
            });
            faces.close_list();
            faces.open_list(grouped_cells ? grouped.points.size() : 3 * n_faces);
        } else {
            faces.open_list(n_faces);
        }
        owner.header("labelList", "owner", note.str());
        owner.open_list(n_faces);
        neighbour.header("labelList", "neighbour", note.str());
        neighbour.open_list(static_cast<size_t>(counts.internal_faces));
        const auto put_face = [&](auto& out, int32_t cell, int32_t across, const int32_t* points, int count) {
            if (binary) {
                out[0].bytes(points, sizeof(int32_t) * static_cast<size_t>(count));
            } else {
                out[0].number(count, '(');
                for (int i = 0; i < count; ++i) out[0].number(points[i], i + 1 < count ? ' ' : ')');
                out[0].append("\n");
            }
            put_label(out[1], cell, binary);
            if (across >= 0) put_label(out[2], across, binary);
        };
        if (grouped_cells)
            stream_blocks<3>(grouped.blocks(), {&faces, &owner, &neighbour}, [&](size_t b, auto& out) {
                grouped.faces(b, [&](int32_t cell, int32_t across, const int32_t* points, int count) {
                    put_face(out, cell, across, points, count);
                });
            });
        else
            stream_blocks<3>(order.face_blocks(), {&faces, &owner, &neighbour}, [&](size_t b, auto& out) {
                order.faces(b, [&](int32_t cell, int32_t across, const Triangle& points) {
                    put_face(out, cell, across, points.data(), 3);
                });
            });
        for (FoamFile* file : {&faces, &owner, &neighbour}) {
            file->close_list();
            file->finish();
        }
    }
    {
        FoamFile w = open("boundary");
        w.header("polyBoundaryMesh", "boundary");
        std::ostringstream out;
        out << patch_count << "\n(\n";
        int64_t start = counts.internal_faces;
        for (int32_t p = 0; p < patch_count; ++p) {
            out << "    " << patch_name(mesh, p) << "\n    {\n        type            " << types[p] << ";\n";
            if (types[p] == "wall") out << "        inGroups        List<word> 1(wall);\n";
            out << "        nFaces          " << counts.patch_faces[p] << ";\n        startFace       " << start
                << ";\n    }\n";
            start += counts.patch_faces[p];
        }
        out << ")\n";
        w.text(out.str());
        w.finish();
    }
    if (options.faces) {
        PolyMeshFaces& out = *options.faces;
        out = {};
        out.owner.reserve(n_faces);
        out.neighbour.reserve(static_cast<size_t>(counts.internal_faces));
        const auto keep = [&](int32_t cell, int32_t across, const int32_t* points, int count) {
            out.points.insert(out.points.end(), points, points + count);
            out.offsets.push_back(static_cast<int32_t>(out.points.size()));
            out.owner.push_back(cell);
            if (across >= 0) out.neighbour.push_back(across);
        };
        if (options.cell_of_tet)
            for (size_t b = 0; b < grouped.blocks(); ++b) grouped.faces(b, keep);
        else
            for (size_t b = 0; b < order.face_blocks(); ++b)
                order.faces(b, [&](int32_t cell, int32_t across, const Triangle& points) {
                    keep(cell, across, points.data(), 3);
                });
    }
    commit_or_stage(outputs, options.staged);
    return counts;
}

} // namespace scalemesh
