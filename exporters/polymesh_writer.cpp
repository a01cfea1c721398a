#include "exporters/polymesh_writer.h"

#include "core/atomic_file.h"
#include "core/errors.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>
#include <string_view>

namespace scalemesh {

namespace {

struct PolyFace {
    Triangle points; // normal from owner to neighbour (or out of the mesh)
    int32_t owner;
    int32_t neighbour; // -1 on the boundary
    int32_t patch;     // boundary only
};

std::array<int32_t, 3> sorted_key(const Triangle& t)
{
    std::array<int32_t, 3> k{t[0], t[1], t[2]};
    std::sort(k.begin(), k.end());
    return k;
}

// A writer of OpenFOAM tokens, ASCII or binary blocks. Numbers are formatted
// with std::to_chars into a buffer that goes to the file a megabyte at a time,
// so a large mesh is neither held as text nor passed through iostream's
// per-number formatting.
class FoamWriter {
public:
    FoamWriter(const std::filesystem::path& path, bool binary) : out_(path, std::ios::binary), binary_(binary)
    {
        if (!out_) throw IoError(path.string(), "cannot open for writing");
        buffer_.reserve(kBufferBytes + 256);
    }

    void header(const std::string& cls, const std::string& object, const std::string& note = "")
    {
        text("FoamFile\n{\n    version     2.0;\n    format      ");
        text(binary_ ? "binary" : "ascii");
        text(";\n    arch        \"LSB;label=32;scalar=64\";\n    class       ");
        text(cls);
        text(";\n    location    \"constant/polyMesh\";\n");
        if (!note.empty()) {
            text("    note        \"");
            text(note);
            text("\";\n");
        }
        text("    object      ");
        text(object);
        text(";\n}\n\n");
    }

    // A labelList of n labels, label i being label(i).
    template <typename Label>
    void labels(size_t n, const Label& label)
    {
        number(static_cast<int64_t>(n));
        text("\n(");
        if (!binary_) text("\n");
        for (size_t i = 0; i < n; ++i) {
            const int32_t value = label(i);
            if (binary_) {
                bytes(&value, sizeof value);
            } else {
                number(value);
                character('\n');
            }
        }
        text(")\n");
    }

    void points(const std::vector<Vec3>& points, double scale)
    {
        number(static_cast<int64_t>(points.size()));
        text("\n(");
        if (binary_) {
            for (const Vec3& p : points) {
                const double xyz[3] = {p.x * scale, p.y * scale, p.z * scale};
                bytes(xyz, sizeof xyz);
            }
        } else {
            text("\n");
            for (const Vec3& p : points) {
                character('(');
                for (int k = 0; k < 3; ++k) {
                    number(p[k] * scale);
                    character(k < 2 ? ' ' : ')');
                }
                character('\n');
            }
        }
        text(")\n");
    }

    void faces(const std::vector<PolyFace>& faces)
    {
        if (binary_) {
            // faceCompactList: the offsets, then the point labels.
            labels(faces.size() + 1, [](size_t f) { return static_cast<int32_t>(3 * f); });
            labels(3 * faces.size(), [&](size_t i) { return faces[i / 3].points[i % 3]; });
            return;
        }
        number(static_cast<int64_t>(faces.size()));
        text("\n(\n");
        for (const PolyFace& f : faces) {
            text("3(");
            for (int k = 0; k < 3; ++k) {
                number(f.points[k]);
                character(k < 2 ? ' ' : ')');
            }
            character('\n');
        }
        text(")\n");
    }

    void text(std::string_view s)
    {
        buffer_.append(s);
        spill();
    }

    void finish(const std::filesystem::path& path)
    {
        text("\n// ************************************************************************* //\n");
        flush();
        out_.flush();
        if (!out_) throw IoError(path.string(), "cannot write the file (disk full?)");
    }

private:
    static constexpr size_t kBufferBytes = size_t(1) << 20;

    void character(char c)
    {
        buffer_.push_back(c);
        spill();
    }

    template <typename Number>
    void number(Number value)
    {
        char digits[32];
        const auto r = std::to_chars(digits, digits + sizeof digits, value);
        buffer_.append(digits, r.ptr);
        spill();
    }

    void bytes(const void* data, size_t size)
    {
        buffer_.append(static_cast<const char*>(data), size);
        spill();
    }

    void spill()
    {
        if (buffer_.size() >= kBufferBytes) flush();
    }

    void flush()
    {
        out_.write(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
        buffer_.clear();
    }

    std::ofstream out_;
    bool binary_;
    std::string buffer_;
};

std::string patch_name(const TetMesh& mesh, int32_t patch)
{
    if (patch < static_cast<int32_t>(mesh.patch_names.size())) return mesh.patch_names[patch];
    return patch == 0 ? "wall" : "patch_" + std::to_string(patch);
}

} // namespace

PolyMeshCounts write_polymesh(const TetMesh& mesh, const std::filesystem::path& case_dir, const PolyMeshOptions& options)
{
    // Validate first: nothing the next tool would choke on is written.
    if (mesh.tets.empty()) throw StageError("polyMesh export", "the mesh has no cells");
    TetFaceAdjacency computed;
    if (!options.adjacency) computed = tet_face_adjacency(mesh);
    const TetFaceAdjacency& adjacency = options.adjacency ? *options.adjacency : computed;
    const TetMeshFacts facts = tet_mesh_facts(mesh, adjacency);
    if (facts.nonpositive_tets > 0)
        throw StageError("polyMesh export", std::to_string(facts.nonpositive_tets) +
                                                " tets have zero or negative volume (inverted cells)");
    if (facts.overshared_faces > 0)
        throw StageError("polyMesh export", std::to_string(facts.overshared_faces) + " faces are shared by more than two tets");
    if (!facts.boundary_matches)
        throw StageError("polyMesh export", "the mesh's open faces (" + std::to_string(facts.boundary_faces) +
                                                ") are not exactly its boundary faces (" +
                                                std::to_string(mesh.boundary_faces.size()) + "), same orientation");
    if (!mesh.boundary_patch.empty() && mesh.boundary_patch.size() != mesh.boundary_faces.size())
        throw StageError("polyMesh export", "boundary_patch does not have one entry per boundary face");

    // Patch of each boundary face, by its sorted point ids.
    std::vector<std::pair<std::array<int32_t, 3>, int32_t>> patch_of;
    patch_of.reserve(mesh.boundary_faces.size());
    int32_t patch_count = 1;
    for (size_t f = 0; f < mesh.boundary_faces.size(); ++f) {
        const int32_t patch = mesh.boundary_patch.empty() ? 0 : mesh.boundary_patch[f];
        if (patch < 0) throw StageError("polyMesh export", "boundary face " + std::to_string(f) + " has a negative patch id");
        patch_count = std::max(patch_count, patch + 1);
        patch_of.emplace_back(sorted_key(mesh.boundary_faces[f]), patch);
    }
    std::sort(patch_of.begin(), patch_of.end());

    // Cells in order; each cell owns the faces it shares with higher cells,
    // taken in the order of those neighbours: upper-triangular order without
    // sorting the faces. Its outward orientation points to the neighbour.
    std::vector<PolyFace> faces, boundary;
    faces.reserve(2 * mesh.tets.size() + mesh.boundary_faces.size() / 2 + 1);
    boundary.reserve(mesh.boundary_faces.size());
    for (int32_t t = 0; t < static_cast<int32_t>(mesh.tets.size()); ++t) {
        const size_t first = faces.size();
        for (int k = 0; k < 4; ++k) {
            const int32_t across = adjacency.across[4 * size_t(t) + k];
            const Triangle points = tet_face(mesh.tets[t], k);
            if (across > t) {
                faces.push_back({points, t, across, -1});
            } else if (across == TetFaceAdjacency::kBoundary) {
                const auto it = std::lower_bound(patch_of.begin(), patch_of.end(), std::make_pair(sorted_key(points), INT32_MIN));
                boundary.push_back({points, t, -1, it->second});
            }
        }
        std::sort(faces.begin() + first, faces.end(),
                  [](const PolyFace& a, const PolyFace& b) { return a.neighbour < b.neighbour; });
    }
    const size_t n_internal = faces.size();
    std::stable_sort(boundary.begin(), boundary.end(), [](const PolyFace& a, const PolyFace& b) { return a.patch < b.patch; });

    PolyMeshCounts counts;
    counts.points = static_cast<int64_t>(mesh.points.size());
    counts.cells = static_cast<int64_t>(mesh.tets.size());
    counts.internal_faces = static_cast<int64_t>(n_internal);
    counts.faces = counts.internal_faces + static_cast<int64_t>(boundary.size());
    counts.patch_faces.assign(patch_count, 0);
    for (const PolyFace& f : boundary) ++counts.patch_faces[f.patch];

    const std::filesystem::path dir = case_dir / "constant" / "polyMesh";
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) throw IoError(dir.string(), "cannot create the directory: " + ec.message());

    std::vector<std::unique_ptr<AtomicOutput>> outputs;
    auto open = [&](const char* name) {
        outputs.push_back(std::make_unique<AtomicOutput>(dir / name));
        return FoamWriter(outputs.back()->temporary(), options.binary);
    };
    std::ostringstream note;
    note << "nPoints:" << counts.points << " nCells:" << counts.cells << " nFaces:" << counts.faces
         << " nInternalFaces:" << counts.internal_faces;

    {
        FoamWriter w = open("points");
        w.header("vectorField", "points");
        if (!(options.scale > 0) || !std::isfinite(options.scale))
            throw StageError("polyMesh export", "the coordinate scale must be a positive number");
        w.points(mesh.points, options.scale);
        w.finish(dir / "points");
    }
    faces.insert(faces.end(), boundary.begin(), boundary.end());
    {
        FoamWriter w = open("faces");
        w.header(options.binary ? "faceCompactList" : "faceList", "faces");
        w.faces(faces);
        w.finish(dir / "faces");
    }
    {
        FoamWriter w = open("owner");
        w.header("labelList", "owner", note.str());
        w.labels(faces.size(), [&](size_t f) { return faces[f].owner; });
        w.finish(dir / "owner");
    }
    {
        FoamWriter w = open("neighbour");
        w.header("labelList", "neighbour", note.str());
        w.labels(n_internal, [&](size_t f) { return faces[f].neighbour; });
        w.finish(dir / "neighbour");
    }
    {
        FoamWriter w = open("boundary");
        w.header("polyBoundaryMesh", "boundary");
        std::ostringstream out;
        out << patch_count << "\n(\n";
        int64_t start = counts.internal_faces;
        for (int32_t p = 0; p < patch_count; ++p) {
            const std::string type = p < static_cast<int32_t>(options.patch_types.size()) ? options.patch_types[p] : "wall";
            if (type != "wall" && type != "patch")
                throw StageError("polyMesh export", "patch type '" + type + "' is neither wall nor patch");
            out << "    " << patch_name(mesh, p) << "\n    {\n        type            " << type << ";\n";
            if (type == "wall") out << "        inGroups        List<word> 1(wall);\n";
            out << "        nFaces          " << counts.patch_faces[p] << ";\n        startFace       " << start
                << ";\n    }\n";
            start += counts.patch_faces[p];
        }
        out << ")\n";
        w.text(out.str());
        w.finish(dir / "boundary");
    }
    if (options.staged) {
        for (auto& out : outputs) options.staged->push_back(std::move(out));
    } else {
        commit_all(outputs);
    }
    return counts;
}

} // namespace scalemesh
