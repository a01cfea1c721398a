#include "exporters/polymesh_decompose.h"

#include "core/errors.h"
#include "exporters/foam_file.h"

#include <algorithm>
#include <charconv>
#include <limits>
#include <memory>
#include <numeric>

namespace scalemesh {

namespace {

constexpr const char* kStage = "OpenFOAM decomposition";

void bisect(std::vector<int32_t>& cells, size_t begin, size_t end, int32_t first_part, int32_t parts,
            const std::vector<Vec3>& centres, std::vector<int32_t>& part_of)
{
    if (parts == 1) {
        for (size_t i = begin; i < end; ++i) part_of[cells[i]] = first_part;
        return;
    }
    constexpr double inf = std::numeric_limits<double>::infinity();
    Vec3 low{inf, inf, inf}, high{-inf, -inf, -inf};
    for (size_t i = begin; i < end; ++i)
        for (int k = 0; k < 3; ++k) {
            low[k] = std::min(low[k], centres[cells[i]][k]);
            high[k] = std::max(high[k], centres[cells[i]][k]);
        }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (high[k] - low[k] > high[axis] - low[axis]) axis = k;
    const int32_t lower = parts / 2;
    const size_t split = begin + (end - begin) * static_cast<size_t>(lower) / static_cast<size_t>(parts);
    std::nth_element(cells.begin() + static_cast<std::ptrdiff_t>(begin), cells.begin() + static_cast<std::ptrdiff_t>(split),
                     cells.begin() + static_cast<std::ptrdiff_t>(end), [&](int32_t a, int32_t b) {
                         const double ca = centres[a][axis], cb = centres[b][axis];
                         return ca != cb ? ca < cb : a < b;
                     });
    bisect(cells, begin, split, first_part, lower, centres, part_of);
    bisect(cells, split, end, first_part + lower, parts - lower, centres, part_of);
}

// An ASCII OpenFOAM file built in memory and written under a temporary name.
class AsciiFile {
public:
    AsciiFile(const std::string& cls, const std::string& location, const std::string& object,
              const std::string& note = "")
        : text_(foam_file_header(false, cls, location, object, note))
    {
    }

    AsciiFile& operator<<(std::string_view s)
    {
        text_ += s;
        return *this;
    }
    template <typename Number>
    void number(Number value, char after)
    {
        char digits[40];
        char* end = std::to_chars(digits, digits + sizeof digits - 1, value).ptr;
        *end++ = after;
        text_.append(digits, end);
    }
    template <typename Label>
    void label_list(const std::vector<Label>& values)
    {
        number(values.size(), '\n');
        text_ += "(\n";
        for (const Label v : values) number(v, '\n');
        text_ += ")\n";
    }

    void write(const std::filesystem::path& path, StagedOutputs& outputs) const
    {
        write_foam_file(path, text_, outputs);
    }

private:
    std::string text_;
};

// One processor's mesh in the serial mesh's numbering.
struct Piece {
    std::vector<int32_t> cells;                // serial cells, ascending (cellProcAddressing)
    std::vector<int32_t> internal;             // serial internal faces, ascending
    std::vector<std::vector<int32_t>> patches; // serial boundary faces per serial patch
    // Per neighbouring processor, ascending: the serial faces shared with
    // it, ascending, + (face + 1) where this piece holds the serial owner.
    std::vector<std::pair<int32_t, std::vector<int32_t>>> shared;
};

std::vector<int32_t>& shared_with(Piece& piece, int32_t other)
{
    auto at = std::lower_bound(piece.shared.begin(), piece.shared.end(), other,
                               [](const auto& entry, int32_t p) { return entry.first < p; });
    if (at == piece.shared.end() || at->first != other) at = piece.shared.insert(at, {other, {}});
    return at->second;
}

// Checks the pieces against the serial mesh: each processor patch matched
// by its neighbour's, face for face (flipped), and each serial face in one
// piece as it is (a shared face, on its owner's side).
void check_pieces(const std::vector<Piece>& pieces, size_t n_faces)
{
    std::vector<int32_t> seen(n_faces, 0);
    for (size_t p = 0; p < pieces.size(); ++p) {
        if (pieces[p].cells.empty())
            throw StageError(kStage, "processor " + std::to_string(p) + " has no cells");
        for (int32_t f : pieces[p].internal) ++seen[f];
        for (const auto& patch : pieces[p].patches)
            for (int32_t f : patch) ++seen[f];
        for (const auto& [other, list] : pieces[p].shared) {
            const auto& back = pieces[other].shared;
            const auto at = std::find_if(back.begin(), back.end(), [&](const auto& e) { return e.first == int32_t(p); });
            bool matched = at != back.end() && at->second.size() == list.size();
            for (size_t i = 0; matched && i < list.size(); ++i) matched = at->second[i] == -list[i];
            if (!matched)
                throw StageError(kStage, "the faces processor " + std::to_string(p) + " shares with processor " +
                                             std::to_string(other) + " are not the ones it shares back");
            for (int32_t f : list)
                if (f > 0) ++seen[f - 1];
        }
    }
    for (size_t f = 0; f < seen.size(); ++f)
        if (seen[f] != 1)
            throw StageError(kStage, "serial face " + std::to_string(f) + " is kept in " + std::to_string(seen[f]) +
                                         " processor meshes, not one");
}

void write_piece(const Piece& piece, int32_t me, const std::vector<int32_t>& local_cell, const std::vector<Vec3>& points,
                 const PolyMeshFaces& faces, const DecomposeOptions& options, const std::filesystem::path& dir,
                 std::vector<int32_t>& local_point, StagedOutputs& outputs)
{
    // The faces in order, signed as in faceProcAddressing.
    std::vector<int32_t> order;
    for (int32_t f : piece.internal) order.push_back(f + 1);
    for (const auto& patch : piece.patches)
        for (int32_t f : patch) order.push_back(f + 1);
    for (const auto& entry : piece.shared) order.insert(order.end(), entry.second.begin(), entry.second.end());

    std::vector<int32_t> used;
    for (int32_t signed_face : order) {
        const int32_t f = std::abs(signed_face) - 1;
        for (int32_t i = faces.offsets[f]; i < faces.offsets[f + 1]; ++i)
            if (local_point[faces.points[i]] < 0) local_point[faces.points[i]] = 0, used.push_back(faces.points[i]);
    }
    std::sort(used.begin(), used.end());
    for (size_t i = 0; i < used.size(); ++i) local_point[used[i]] = static_cast<int32_t>(i);

    const std::string note = "nPoints:" + std::to_string(used.size()) + " nCells:" + std::to_string(piece.cells.size()) +
                             " nFaces:" + std::to_string(order.size()) +
                             " nInternalFaces:" + std::to_string(piece.internal.size());
    const std::string location = "constant/polyMesh";
    AsciiFile point_file("vectorField", location, "points");
    point_file.number(used.size(), '\n');
    point_file << "(\n";
    for (int32_t p : used) {
        point_file << "(";
        point_file.number(points[p].x * options.scale, ' ');
        point_file.number(points[p].y * options.scale, ' ');
        point_file.number(points[p].z * options.scale, ')');
        point_file << "\n";
    }
    point_file << ")\n";

    AsciiFile face_file("faceList", location, "faces");
    AsciiFile owner_file("labelList", location, "owner", note), neighbour_file("labelList", location, "neighbour", note);
    std::vector<int32_t> owner, neighbour;
    face_file.number(order.size(), '\n');
    face_file << "(\n";
    for (size_t at = 0; at < order.size(); ++at) {
        const int32_t signed_face = order[at], f = std::abs(signed_face) - 1;
        const int32_t* p = faces.points.data() + faces.offsets[f];
        const int32_t count = faces.offsets[f + 1] - faces.offsets[f];
        face_file.number(count, '(');
        // Flipped: the first point kept, the rest reversed.
        for (int32_t i = 0; i < count; ++i)
            face_file.number(local_point[p[signed_face > 0 || i == 0 ? i : count - i]], i + 1 < count ? ' ' : ')');
        face_file << "\n";
        owner.push_back(local_cell[signed_face > 0 ? faces.owner[f] : faces.neighbour[f]]);
        if (at < piece.internal.size()) neighbour.push_back(local_cell[faces.neighbour[f]]);
    }
    face_file << ")\n";
    owner_file.label_list(owner);
    neighbour_file.label_list(neighbour);

    AsciiFile boundary("polyBoundaryMesh", location, "boundary");
    const size_t patches = piece.patches.size() + piece.shared.size();
    boundary.number(patches, '\n');
    boundary << "(\n";
    size_t start = piece.internal.size();
    std::vector<int32_t> patch_of;
    for (size_t q = 0; q < patches; ++q) {
        const bool serial = q < piece.patches.size();
        const size_t count = serial ? piece.patches[q].size() : piece.shared[q - piece.patches.size()].second.size();
        const std::string type = serial ? options.patch_types[q] : "processor";
        if (serial) {
            boundary << "    " << options.patch_names[q] << "\n    {\n        type            " << type << ";\n";
            if (type == "wall") boundary << "        inGroups        List<word> 1(wall);\n";
        } else {
            const std::string other = std::to_string(piece.shared[q - piece.patches.size()].first);
            boundary << "    procBoundary" << std::to_string(me) << "to" << other
                     << "\n    {\n        type            processor;\n"
                        "        inGroups        List<word> 1(processor);\n";
        }
        boundary << "        nFaces          " << std::to_string(count) << ";\n        startFace       "
                 << std::to_string(start) << ";\n";
        if (!serial)
            boundary << "        matchTolerance  0.0001;\n        transform       unknown;\n        myProcNo        "
                     << std::to_string(me) << ";\n        neighbProcNo    "
                     << std::to_string(piece.shared[q - piece.patches.size()].first) << ";\n";
        boundary << "    }\n";
        start += count;
        patch_of.push_back(serial ? static_cast<int32_t>(q) : -1);
    }
    boundary << ")\n";

    AsciiFile cell_addressing("labelList", location, "cellProcAddressing");
    cell_addressing.label_list(piece.cells);
    AsciiFile face_addressing("labelList", location, "faceProcAddressing");
    face_addressing.label_list(order);
    AsciiFile point_addressing("labelList", location, "pointProcAddressing");
    point_addressing.label_list(used);
    AsciiFile boundary_addressing("labelList", location, "boundaryProcAddressing");
    boundary_addressing.label_list(patch_of);

    const std::filesystem::path mesh = dir / ("processor" + std::to_string(me)) / "constant" / "polyMesh";
    point_file.write(mesh / "points", outputs);
    face_file.write(mesh / "faces", outputs);
    owner_file.write(mesh / "owner", outputs);
    neighbour_file.write(mesh / "neighbour", outputs);
    boundary.write(mesh / "boundary", outputs);
    cell_addressing.write(mesh / "cellProcAddressing", outputs);
    face_addressing.write(mesh / "faceProcAddressing", outputs);
    point_addressing.write(mesh / "pointProcAddressing", outputs);
    boundary_addressing.write(mesh / "boundaryProcAddressing", outputs);
    for (int32_t p : used) local_point[p] = -1;
}

} // namespace

std::vector<int32_t> bisect_cells(const std::vector<Vec3>& centres, int32_t parts)
{
    if (parts < 1 || static_cast<size_t>(parts) > centres.size())
        throw InputError("cannot cut " + std::to_string(centres.size()) + " cells into " + std::to_string(parts) +
                             " processor meshes",
                         "give decompose between 1 and the cell count");
    std::vector<int32_t> cells(centres.size()), part_of(centres.size(), 0);
    std::iota(cells.begin(), cells.end(), 0);
    bisect(cells, 0, cells.size(), 0, parts, centres, part_of);
    return part_of;
}

DecomposeCounts write_decomposed_polymesh(const std::vector<Vec3>& points, const PolyMeshFaces& faces,
                                          const std::vector<int64_t>& patch_faces,
                                          const std::filesystem::path& case_dir, const DecomposeOptions& options)
{
    const size_t n_faces = faces.owner.size(), internal = faces.neighbour.size();
    if (faces.offsets.size() != n_faces + 1 || internal > n_faces ||
        std::accumulate(patch_faces.begin(), patch_faces.end(), int64_t(0)) != static_cast<int64_t>(n_faces - internal) ||
        options.patch_names.size() != patch_faces.size() || options.patch_types.size() != patch_faces.size())
        throw std::invalid_argument("the faces, patch counts and patch names are not of one polyMesh");
    int32_t cells = 0;
    for (int32_t c : faces.owner) cells = std::max(cells, c + 1);
    for (int32_t c : faces.neighbour) cells = std::max(cells, c + 1);
    if (options.processors < 1 || options.processors > cells)
        throw InputError("decompose = " + std::to_string(options.processors) + " asks for more processor meshes than the " +
                             std::to_string(cells) + " cells (or fewer than 1)",
                         "give decompose between 1 and the cell count");

    // The cell centres for the cut: the mean of their faces' point means.
    std::vector<Vec3> centres(static_cast<size_t>(cells));
    std::vector<int32_t> face_count(static_cast<size_t>(cells), 0);
    for (size_t f = 0; f < n_faces; ++f) {
        Vec3 mean;
        for (int32_t i = faces.offsets[f]; i < faces.offsets[f + 1]; ++i) mean += points[faces.points[i]];
        mean /= faces.offsets[f + 1] - faces.offsets[f];
        centres[faces.owner[f]] += mean, ++face_count[faces.owner[f]];
        if (f < internal) centres[faces.neighbour[f]] += mean, ++face_count[faces.neighbour[f]];
    }
    for (int32_t c = 0; c < cells; ++c) centres[c] /= std::max(face_count[c], 1);
    const std::vector<int32_t> part = bisect_cells(centres, options.processors);

    std::vector<Piece> pieces(static_cast<size_t>(options.processors));
    std::vector<int32_t> local_cell(static_cast<size_t>(cells));
    for (int32_t c = 0; c < cells; ++c) {
        local_cell[c] = static_cast<int32_t>(pieces[part[c]].cells.size());
        pieces[part[c]].cells.push_back(c);
    }
    for (Piece& piece : pieces) piece.patches.resize(patch_faces.size());
    DecomposeCounts counts;
    for (size_t f = 0; f < internal; ++f) {
        const int32_t a = part[faces.owner[f]], b = part[faces.neighbour[f]];
        const int32_t face = static_cast<int32_t>(f);
        if (a == b) {
            pieces[a].internal.push_back(face);
        } else {
            shared_with(pieces[a], b).push_back(face + 1);
            shared_with(pieces[b], a).push_back(-(face + 1));
            ++counts.processor_faces;
        }
    }
    for (size_t q = 0, f = internal; q < patch_faces.size(); ++q)
        for (int64_t i = 0; i < patch_faces[q]; ++i, ++f)
            pieces[part[faces.owner[f]]].patches[q].push_back(static_cast<int32_t>(f));
    check_pieces(pieces, n_faces);

    StagedOutputs outputs;
    std::vector<int32_t> local_point(points.size(), -1);
    for (size_t p = 0; p < pieces.size(); ++p) {
        write_piece(pieces[p], static_cast<int32_t>(p), local_cell, points, faces, options, case_dir, local_point,
                    outputs);
        counts.cells.push_back(static_cast<int64_t>(pieces[p].cells.size()));
        counts.processor_patches += static_cast<int64_t>(pieces[p].shared.size());
    }
    counts.processor_patches /= 2;

    AsciiFile decomposition("labelList", "constant", "cellDecomposition");
    decomposition.label_list(part);
    decomposition.write(case_dir / "constant" / "cellDecomposition", outputs);
    AsciiFile dict("dictionary", "system", "decomposeParDict");
    dict << "// Written by scalemesh with processor0 .. processor" << std::to_string(options.processors - 1)
         << ": the cells cut by recursive\n// bisection of their centres across the longest side (scalemesh's\n"
            "// bisect_cells). `decomposePar -force` with this dictionary writes the same\n"
            "// pieces; method scotch instead cuts fewer faces (docs/case-file.md).\n\n"
         << "numberOfSubdomains " << std::to_string(options.processors)
         << ";\n\nmethod          manual;\n\nmanualCoeffs\n{\n    dataFile        \"cellDecomposition\";\n}\n";
    dict.write(case_dir / "system" / "decomposeParDict", outputs);

    commit_or_stage(outputs, options.staged);
    return counts;
}

} // namespace scalemesh
