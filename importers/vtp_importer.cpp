// VTK XML PolyData (.vtp) reading, by hand: the XML through expat and the
// DataArrays decoded in importers/vtk_xml.cpp. VTK's own reader would come
// with Debian's libvtk9-dev, about 200 MB of packages for one file format;
// the subset read here (every encoding VTK, VMTK, SimVascular and ParaView
// write: ascii, inline binary, appended raw or base64, zlib-compressed or
// not, either header type and byte order) is what a surface and its face
// labels need.

#include "core/errors.h"
#include "importers/polygon_soup.h"
#include "importers/surface_importer.h"
#include "importers/vtk_xml.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <limits>

namespace scalemesh {

namespace {

using vtk_xml::Array;
using vtk_xml::Element;

// Cell arrays taken as face labels, in order of preference: SimVascular's
// ModelFaceID and CapID, VMTK's CellEntityIds, then common generic names.
constexpr std::array<const char*, 5> kLabelNames = {"ModelFaceID", "CapID", "CellEntityIds", "FaceID", "GroupIds"};

struct Polygons {
    PolygonSoup soup;
    std::vector<int32_t> labels; // per polygon, when `label_name` is set
    std::string label_name;
};

bool is_label_array(const Element& e)
{
    const auto type = vtk_xml::scalar_type(e.attribute("type"));
    const std::string components = e.attribute("NumberOfComponents");
    return e.name == "DataArray" && type && vtk_xml::is_integer(*type) && (components.empty() || components == "1");
}

// The name of the cell array that labels the faces, from the first piece:
// the first of kLabelNames present, else the only integer cell array.
std::string label_array_name(const Element& piece)
{
    const Element* cells = piece.child("CellData");
    if (!cells) return "";
    std::vector<std::string> integer_arrays;
    for (const Element& e : cells->children)
        if (is_label_array(e)) integer_arrays.push_back(e.attribute("Name"));
    for (const char* name : kLabelNames)
        if (std::find(integer_arrays.begin(), integer_arrays.end(), name) != integer_arrays.end()) return name;
    return integer_arrays.size() == 1 ? integer_arrays.front() : "";
}

class VtpReader {
public:
    VtpReader(const std::string& bytes, const std::filesystem::path& path)
        : doc_(bytes, "PolyData", path.string() + " is not a VTK PolyData surface scalemesh reads: ")
    {
    }

    Polygons read()
    {
        std::vector<const Element*> pieces;
        for (const Element& e : doc_.dataset().children)
            if (e.name == "Piece") pieces.push_back(&e);
        if (pieces.empty()) doc_.fail("it holds no <Piece>", "export a surface that has triangles");
        Polygons out;
        out.label_name = label_array_name(*pieces.front());
        for (size_t p = 0; p < pieces.size(); ++p) read_piece(*pieces[p], p, out);
        return out;
    }

private:
    void read_piece(const Element& piece, size_t index, Polygons& out)
    {
        const std::string where = "piece " + std::to_string(index);
        for (const char* kind : {"NumberOfVerts", "NumberOfLines", "NumberOfStrips"})
            if (count(piece, kind, where) != 0)
                doc_.fail(where + " has " + kind + " = " + piece.attribute(kind) +
                              ": only polygons (<Polys>) make a surface",
                          "triangulate the surface and remove vertices and lines (ParaView: Extract Surface, "
                          "Triangulate)");
        const uint64_t n_points = count(piece, "NumberOfPoints", where);
        const uint64_t n_polys = count(piece, "NumberOfPolys", where);
        const Element* points = first_array(piece.child("Points"));
        const Element* connectivity = named_array(piece.child("Polys"), "connectivity");
        const Element* offsets = named_array(piece.child("Polys"), "offsets");
        if (n_points > 0 && !points) doc_.fail(where + " has no <Points> DataArray");
        if (n_polys > 0 && (!connectivity || !offsets))
            doc_.fail(where + " has no <Polys> connectivity and offsets DataArrays");

        PolygonSoup& soup = out.soup;
        const size_t base = soup.points.size();
        if (points && n_points > 0) {
            const Array xyz = doc_.read(*points, where + " points", 3 * n_points);
            if (xyz.components != 3) doc_.fail(where + ": its points do not have NumberOfComponents=\"3\"");
            for (uint64_t i = 0; i < n_points; ++i)
                soup.points.push_back({xyz.value(3 * i), xyz.value(3 * i + 1), xyz.value(3 * i + 2)});
        }
        if (n_polys == 0) return;

        // VTK 9 writes n + 1 offsets starting at 0, older files the n ends.
        const Array ends = integers(*offsets, where + " offsets", std::nullopt);
        uint64_t first = 0;
        if (ends.size() == n_polys + 1 && ends.integer(0) == 0) first = 1;
        else if (ends.size() != n_polys)
            doc_.fail(where + " announces " + std::to_string(n_polys) + " polygons but holds " +
                      std::to_string(ends.size()) + " offsets");
        const std::optional<int64_t> last = ends.integer(ends.size() - 1);
        if (!last || *last < 0)
            doc_.fail(where + ": its last polygon offset is not a count of connectivity entries");
        const Array corners = integers(*connectivity, where + " connectivity", static_cast<uint64_t>(*last));

        int64_t previous = 0;
        for (uint64_t k = first; k < ends.size(); ++k) {
            const std::optional<int64_t> end = ends.integer(k);
            if (!end || *end < previous || *end > *last)
                doc_.fail(where + ": its polygon offsets are not increasing within the " +
                          std::to_string(corners.size()) + " connectivity entries");
            for (int64_t c = previous; c < *end; ++c) {
                const std::optional<int64_t> corner = corners.integer(static_cast<uint64_t>(c));
                // A piece's indices stay within its own points.
                if (!corner || *corner < 0 || static_cast<uint64_t>(*corner) >= n_points)
                    doc_.fail(where + " has a polygon corner outside its " + std::to_string(n_points) + " points",
                              "the file is damaged or its indices are off: export it again");
                soup.corners.push_back(*corner + static_cast<int64_t>(base));
            }
            soup.offsets.push_back(static_cast<int64_t>(soup.corners.size()));
            previous = *end;
        }
        if (!out.label_name.empty()) read_labels(piece, where, n_polys, out);
    }

    void read_labels(const Element& piece, const std::string& where, uint64_t n_polys, Polygons& out)
    {
        const Element* array = named_array(piece.child("CellData"), out.label_name);
        if (!array || !is_label_array(*array))
            doc_.fail(where + " has no integer cell array " + out.label_name + ", which the first piece labels its "
                                                                                 "faces with",
                      "give every piece the same cell arrays (ParaView: Merge Blocks, then Clean)");
        const std::string what = where + " cell array " + out.label_name;
        const Array labels = doc_.read(*array, what);
        if (labels.size() != n_polys)
            doc_.fail(what + " holds " + std::to_string(labels.size()) + " values for " + std::to_string(n_polys) +
                          " polygons",
                      "the labels must have one value per polygon: export the surface again");
        for (uint64_t i = 0; i < n_polys; ++i) {
            const std::optional<int64_t> v = labels.integer(i);
            if (!v || *v < std::numeric_limits<int32_t>::min() || *v > std::numeric_limits<int32_t>::max())
                doc_.fail(what + " holds a value beyond the 32-bit integers at polygon " + std::to_string(i),
                          "renumber the face labels");
            out.labels.push_back(static_cast<int32_t>(*v));
        }
    }

    Array integers(const Element& e, const std::string& what, std::optional<uint64_t> expected)
    {
        const auto type = vtk_xml::scalar_type(e.attribute("type"));
        if (type && !vtk_xml::is_integer(*type))
            doc_.fail(what + " are of type " + e.attribute("type") + ", not an integer type");
        return doc_.read(e, what, expected);
    }

    static const Element* first_array(const Element* parent)
    {
        return parent ? parent->child("DataArray") : nullptr;
    }

    static const Element* named_array(const Element* parent, const std::string& name)
    {
        if (!parent) return nullptr;
        for (const Element& e : parent->children)
            if (e.name == "DataArray" && e.attribute("Name") == name) return &e;
        return nullptr;
    }

    uint64_t count(const Element& piece, const std::string& key, const std::string& where)
    {
        const std::string text = piece.attribute(key);
        if (text.empty()) return 0;
        uint64_t value = 0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
        if (error != std::errc() || end != text.data() + text.size())
            doc_.fail(where + ": " + key + "=\"" + text.substr(0, 40) + "\" is not a count");
        // Beyond int32 triangles anyway; keeps every product below 2^64.
        if (value > (uint64_t{1} << 40))
            doc_.fail(where + ": " + key + "=\"" + text + "\" is more than scalemesh reads",
                      "decimate the surface first");
        return value;
    }

    vtk_xml::Document doc_;
};

Polygons read_polygons(const std::filesystem::path& path, double scale)
{
    require_scale(scale);
    const std::string bytes = read_file_bytes(path);
    return VtpReader(bytes, path).read();
}

} // namespace

SurfaceMesh read_vtp(const std::filesystem::path& path, double scale)
{
    return read_vtp_labelled(path, scale).mesh;
}

LabelledSurface read_vtp_labelled(const std::filesystem::path& path, double scale)
{
    const Polygons polygons = read_polygons(path, scale);
    LabelledSurface out;
    if (polygons.label_name.empty()) {
        out.mesh = weld_polygons(polygons.soup, scale, path);
        return out;
    }
    out.mesh = weld_polygons(polygons.soup, scale, path, polygons.labels, out.labels.per_triangle);
    out.labels.source = "cell array " + polygons.label_name;
    return out;
}

} // namespace scalemesh
