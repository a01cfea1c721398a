#include "exporters/polymesh_writer.h"

#include "core/atomic_file.h"
#include "core/errors.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>

namespace scalemesh {

namespace {

// Faces of tet (a, b, c, d), each counter-clockwise seen from outside the tet.
constexpr int kFaces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

struct TetFace {
    std::array<int32_t, 3> key; // sorted point ids
    int32_t tet;
    int8_t local; // which face of the tet
    bool operator<(const TetFace& o) const { return key != o.key ? key < o.key : tet < o.tet; }
};

struct PolyFace {
    Triangle points; // normal from owner to neighbour (or out of the mesh)
    int32_t owner;
    int32_t neighbour; // -1 on the boundary
    int32_t patch;     // boundary only
};

Triangle tet_face(const Tet& t, int local)
{
    return {t[kFaces[local][0]], t[kFaces[local][1]], t[kFaces[local][2]]};
}

std::array<int32_t, 3> sorted_key(const Triangle& t)
{
    std::array<int32_t, 3> k{t[0], t[1], t[2]};
    std::sort(k.begin(), k.end());
    return k;
}

// A buffered writer of OpenFOAM tokens, ASCII or binary blocks.
class FoamWriter {
public:
    FoamWriter(const std::filesystem::path& path, bool binary) : out_(path, std::ios::binary), binary_(binary)
    {
        if (!out_) throw IoError(path.string(), "cannot open for writing");
    }

    void header(const std::string& cls, const std::string& object, const std::string& note = "")
    {
        out_ << "FoamFile\n{\n    version     2.0;\n    format      " << (binary_ ? "binary" : "ascii")
             << ";\n    arch        \"LSB;label=32;scalar=64\";\n    class       " << cls
             << ";\n    location    \"constant/polyMesh\";\n";
        if (!note.empty()) out_ << "    note        \"" << note << "\";\n";
        out_ << "    object      " << object << ";\n}\n\n";
    }

    void labels(const std::vector<int32_t>& values)
    {
        out_ << values.size() << "\n(";
        if (binary_) {
            out_.write(reinterpret_cast<const char*>(values.data()), std::streamsize(values.size() * sizeof(int32_t)));
        } else {
            out_ << '\n';
            for (int32_t v : values) out_ << v << '\n';
        }
        out_ << ")\n";
    }

    void points(const std::vector<Vec3>& points, double scale)
    {
        out_ << points.size() << "\n(";
        if (binary_) {
            for (const Vec3& p : points) {
                const double xyz[3] = {p.x * scale, p.y * scale, p.z * scale};
                out_.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
            }
        } else {
            out_ << '\n';
            char buf[64];
            for (const Vec3& p : points) {
                out_ << '(';
                for (int k = 0; k < 3; ++k) {
                    const auto r = std::to_chars(buf, buf + sizeof buf, p[k] * scale);
                    out_.write(buf, r.ptr - buf);
                    out_ << (k < 2 ? ' ' : ')');
                }
                out_ << '\n';
            }
        }
        out_ << ")\n";
    }

    void faces(const std::vector<PolyFace>& faces)
    {
        if (binary_) {
            // faceCompactList: the offsets, then the point labels.
            std::vector<int32_t> offsets(faces.size() + 1), labels;
            labels.reserve(faces.size() * 3);
            for (size_t f = 0; f < faces.size(); ++f) {
                offsets[f + 1] = static_cast<int32_t>(3 * (f + 1));
                labels.insert(labels.end(), faces[f].points.begin(), faces[f].points.end());
            }
            this->labels(offsets);
            this->labels(labels);
            return;
        }
        out_ << faces.size() << "\n(\n";
        for (const PolyFace& f : faces) out_ << "3(" << f.points[0] << ' ' << f.points[1] << ' ' << f.points[2] << ")\n";
        out_ << ")\n";
    }

    std::ostream& raw() { return out_; }

    void finish(const std::filesystem::path& path)
    {
        out_ << "\n// ************************************************************************* //\n";
        out_.flush();
        if (!out_) throw IoError(path.string(), "cannot write the file (disk full?)");
    }

private:
    std::ofstream out_;
    bool binary_;
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
    const TetMeshFacts facts = tet_mesh_facts(mesh);
    if (mesh.tets.empty()) throw StageError("polyMesh export", "the mesh has no cells");
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

    std::vector<TetFace> all;
    all.reserve(mesh.tets.size() * 4);
    for (int32_t t = 0; t < static_cast<int32_t>(mesh.tets.size()); ++t)
        for (int8_t k = 0; k < 4; ++k) all.push_back({sorted_key(tet_face(mesh.tets[t], k)), t, k});
    std::sort(all.begin(), all.end());

    std::vector<PolyFace> internal, boundary;
    internal.reserve(all.size() / 2);
    for (size_t i = 0; i < all.size();) {
        if (i + 1 < all.size() && all[i + 1].key == all[i].key) {
            // The lower tet owns the face; its outward orientation points to the higher.
            internal.push_back({tet_face(mesh.tets[all[i].tet], all[i].local), all[i].tet, all[i + 1].tet, -1});
            i += 2;
        } else {
            const auto it = std::lower_bound(patch_of.begin(), patch_of.end(), std::make_pair(all[i].key, INT32_MIN));
            boundary.push_back({tet_face(mesh.tets[all[i].tet], all[i].local), all[i].tet, -1, it->second});
            i += 1;
        }
    }
    std::sort(internal.begin(), internal.end(), [](const PolyFace& a, const PolyFace& b) {
        return a.owner != b.owner ? a.owner < b.owner : a.neighbour < b.neighbour;
    });
    std::stable_sort(boundary.begin(), boundary.end(), [](const PolyFace& a, const PolyFace& b) {
        return a.patch != b.patch ? a.patch < b.patch : a.owner < b.owner;
    });

    PolyMeshCounts counts;
    counts.points = static_cast<int64_t>(mesh.points.size());
    counts.cells = static_cast<int64_t>(mesh.tets.size());
    counts.internal_faces = static_cast<int64_t>(internal.size());
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
    std::vector<PolyFace> faces = std::move(internal);
    faces.insert(faces.end(), boundary.begin(), boundary.end());
    {
        FoamWriter w = open("faces");
        w.header(options.binary ? "faceCompactList" : "faceList", "faces");
        w.faces(faces);
        w.finish(dir / "faces");
    }
    {
        std::vector<int32_t> owner(faces.size());
        for (size_t f = 0; f < faces.size(); ++f) owner[f] = faces[f].owner;
        FoamWriter w = open("owner");
        w.header("labelList", "owner", note.str());
        w.labels(owner);
        w.finish(dir / "owner");
    }
    {
        std::vector<int32_t> neighbour(static_cast<size_t>(counts.internal_faces));
        for (size_t f = 0; f < neighbour.size(); ++f) neighbour[f] = faces[f].neighbour;
        FoamWriter w = open("neighbour");
        w.header("labelList", "neighbour", note.str());
        w.labels(neighbour);
        w.finish(dir / "neighbour");
    }
    {
        FoamWriter w = open("boundary");
        w.header("polyBoundaryMesh", "boundary");
        std::ostream& out = w.raw();
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
