// The Python module `scalemesh` (pybind11): mesh_surface on NumPy arrays or
// flat sequences in gmsh.py's layout or on a meshio.Mesh, mesh_image on an
// image file or a NumPy array vol[i, j, k], and mesh_gmsh_model on the current
// model of the gmsh.py session, which shares this process's libgmsh with the
// library (src/python/CMakeLists.txt). Results are MeshResult objects: a
// read-only mapping of NumPy arrays (as the dicts the module returned
// before), with the library's writers as methods (write_openfoam, write_msh,
// report, to_meshio). Its type stub is scalemesh.pyi, installed beside it.
// Errors: InputError -> ValueError, StageError -> RuntimeError,
// IoError -> OSError, with the library's message.

#include "scalemesh/scalemesh.h"

#include "pipeline/options_table.h"

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <variant>

namespace py = pybind11;
using namespace pybind11::literals;

namespace {

using scalemesh::MeshLength;
using scalemesh::MeshOptions;
using scalemesh::MeshResult;

// A length option: a number (mm) or a string "<value> mm" / "<value> voxels".
MeshLength length_option(const char* key, const py::handle& value)
{
    if (py::isinstance<py::str>(value)) {
        const std::string text = value.cast<std::string>();
        // std::from_chars: the number as written in Python, whatever the
        // process's LC_NUMERIC (std::strtod follows it).
        // Leading white space and one '+' are skipped, as std::strtod skipped them.
        const char* begin = text.c_str();
        while (std::isspace(static_cast<unsigned char>(*begin))) ++begin;
        if (*begin == '+') ++begin;
        double v = 0;
        const auto [end, error] = std::from_chars(begin, text.c_str() + text.size(), v);
        const bool number = error == std::errc();
        std::string unit(number ? end : begin);
        unit.erase(0, std::min(unit.find_first_not_of(' '), unit.size()));
        if (number && (unit == "mm" || unit.empty())) return MeshLength::mm(v);
        if (number && (unit == "voxels" || unit == "voxel")) return MeshLength::in_voxels(v);
        throw py::value_error(std::string("option ") + key + " = '" + text +
                              "' is not a length. Hint: give a number (mm) or a string such as \"2 mm\" or "
                              "\"0.5 voxels\"");
    }
    return MeshLength::mm(value.cast<double>());
}

// The keywords besides the meshing options' (scalemesh::mesh_option_table).
const char* const other_keywords[] = {"openings", "progress", "gmsh_session"};

// A meshing option's value, from Python, into its MeshOptions member.
void set_option(MeshOptions& o, const scalemesh::OptionInfo& option, const py::handle& value)
{
    std::visit(
        [&](auto member) {
            auto& field = o.*member;
            using T = std::decay_t<decltype(field)>;
            if constexpr (std::is_same_v<T, MeshLength>) {
                field = length_option(option.keyword.c_str(), value);
            } else if constexpr (std::is_same_v<T, std::optional<MeshLength>>) {
                if (value.is_none()) field.reset();
                else field = length_option(option.keyword.c_str(), value);
            } else {
                field = value.cast<T>();
            }
        },
        option.member);
}

// A meshing option's value as Python gives it: a length as a number of mm or
// a string "<value> voxels", an unset length as None.
py::object option_value(const MeshOptions& o, const scalemesh::OptionInfo& option)
{
    const auto length = [](const MeshLength& l) {
        return l.voxels ? py::object(py::str(py::repr(py::float_(l.value)).cast<std::string>() + " voxels"))
                        : py::object(py::float_(l.value));
    };
    return std::visit(
        [&](auto member) -> py::object {
            const auto& field = o.*member;
            using T = std::decay_t<decltype(field)>;
            if constexpr (std::is_same_v<T, MeshLength>) return length(field);
            else if constexpr (std::is_same_v<T, std::optional<MeshLength>>)
                return field ? length(*field) : py::object(py::none());
            else return py::cast(field);
        },
        option.member);
}

// The options' part of the module's docstring: one line per meshing option
// (its kind, range or choices, unit, default and doc), from the table.
std::string options_doc()
{
    const MeshOptions defaults;
    std::string out;
    for (const scalemesh::OptionInfo& option : scalemesh::mesh_option_table()) {
        out += "  " + option.keyword + " (" + scalemesh::option_kind_name(option.kind);
        if (option.kind == scalemesh::OptionKind::number || option.kind == scalemesh::OptionKind::integer)
            out += " in " + scalemesh::range_text(option);
        for (size_t i = 0; i < option.choices.size(); ++i) out += (i == 0 ? ": \"" : " or \"") + option.choices[i] + "\"";
        if (!option.unit.empty()) out += ", " + option.unit;
        out += ", default " + py::repr(option_value(defaults, option)).cast<std::string>() + "): " + option.doc + "\n";
    }
    return out;
}

const char* const opening_keys[] = {"name",   "type",  "point", "normal", "radius",
                                    "border", "inset", "near",  "label",  "extension"};

// A value converted to T, or a TypeError naming where it was given (an
// openings entry's key, an option).
template <class T> T checked_cast(const std::string& where, const py::handle& value, const char* expected)
{
    try {
        return value.cast<T>();
    } catch (const py::cast_error&) {
        throw py::type_error(where + " is " + std::string(py::str(py::type::handle_of(value).attr("__name__"))) +
                             ", not " + expected);
    }
}

std::array<double, 3> opening_vector(const std::string& where, const py::handle& value)
{
    const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
    if (!array || array.size() != 3)
        throw py::value_error(where + " is not 3 numbers. Hint: give [x, y, z] in mm");
    return {array.data()[0], array.data()[1], array.data()[2]};
}

// One [[openings]] table of the case file as a dict with its keys; the
// library checks the values as the case reader does (ValueError naming the
// opening and the key).
scalemesh::MeshOpening opening_option(size_t index, const py::handle& item)
{
    const std::string at = "openings[" + std::to_string(index) + "]";
    if (!py::isinstance<py::dict>(item))
        throw py::type_error(at + " is not a dict. Hint: give openings=[{\"name\": \"inlet\", \"type\": \"inlet\", "
                                  "\"point\": [x, y, z], \"normal\": [nx, ny, nz]}, ...]");
    scalemesh::MeshOpening o;
    for (const auto& [key_handle, value] : item.cast<py::dict>()) {
        const std::string key = py::str(key_handle);
        const std::string where = at + "['" + key + "']";
        if (value.is_none()) continue; // as if not given
        if (key == "name") o.name = checked_cast<std::string>(where, value, "a string");
        else if (key == "type") o.type = checked_cast<std::string>(where, value, "a string (\"inlet\" or \"outlet\")");
        else if (key == "point") o.point = opening_vector(where, value);
        else if (key == "normal") o.normal = opening_vector(where, value);
        else if (key == "near") o.near = opening_vector(where, value);
        else if (key == "radius") o.radius = checked_cast<double>(where, value, "a number (mm)");
        else if (key == "extension") o.extension = checked_cast<double>(where, value, "a number (cap diameters)");
        else if (key == "border") o.border = checked_cast<std::string>(where, value, "a string (\"x-\" ... \"z+\")");
        else if (key == "inset") {
            if (!(py::isinstance<py::str>(value) && value.cast<std::string>() == "auto"))
                o.inset = length_option(where.c_str(), value);
        } else if (key == "label") {
            if (py::isinstance<py::bool_>(value) || !py::isinstance<py::int_>(value))
                throw py::type_error(where + " is not an integer (a face label)");
            const long long label = value.cast<long long>();
            if (label < 0 || label > std::numeric_limits<std::int32_t>::max())
                throw py::value_error(where + " = " + std::to_string(label) + " is not a face label. Hint: give an "
                                      "integer >= 0");
            o.label = static_cast<std::int32_t>(label);
        } else {
            std::string keys;
            for (const char* name : opening_keys) keys += std::string(keys.empty() ? "" : ", ") + name;
            throw py::value_error(at + " has the unknown key '" + key + "'; the keys are: " + keys);
        }
    }
    return o;
}

// MeshOptions from keyword arguments named as its members; the library
// checks the values (ValueError naming the key).
MeshOptions mesh_options(const py::kwargs& kwargs)
{
    MeshOptions o;
    for (const auto& [key_handle, value] : kwargs) {
        const std::string key = key_handle.cast<std::string>();
        try {
            if (const scalemesh::OptionInfo* option = scalemesh::find_option(key)) set_option(o, *option, value);
            else if (key == "gmsh_session") o.host_gmsh_session = value.cast<bool>();
            else if (key == "openings") {
                if (!value.is_none()) {
                    if (py::isinstance<py::dict>(value) || py::isinstance<py::str>(value) ||
                        !py::isinstance<py::sequence>(value))
                        throw py::type_error("openings is not a list of dicts. Hint: give openings=[{\"name\": "
                                             "\"inlet\", \"type\": \"inlet\", ...}, ...]");
                    const py::sequence items = value.cast<py::sequence>();
                    for (size_t i = 0; i < items.size(); ++i) o.openings.push_back(opening_option(i, items[i]));
                }
            } else if (key == "progress") {
                if (!value.is_none()) {
                    auto callback = value.cast<std::function<void(const std::string&, double, const std::string&)>>();
                    // Called on the calling thread, whose GIL is released during the run.
                    o.progress = [callback](const std::string& stage, double seconds, const std::string& summary) {
                        py::gil_scoped_acquire gil;
                        callback(stage, seconds, summary);
                    };
                }
            } else {
                std::string names;
                for (const scalemesh::OptionInfo& option : scalemesh::mesh_option_table())
                    names += (names.empty() ? "" : ", ") + option.keyword;
                for (const char* name : other_keywords) names += std::string(", ") + name;
                throw py::type_error("unexpected keyword argument '" + key + "'; the options are: " + names);
            }
        } catch (const py::cast_error&) {
            // A value of another type (a string for a number, say): one
            // TypeError naming the option, as for every other bad option.
            throw py::type_error(key + " = " + py::repr(value).cast<std::string>() +
                                 " is not of the option's type. Hint: see help(scalemesh) for each option's type");
        }
    }
    return o;
}

template <class T> py::array_t<T> array_2d(const std::vector<T>& flat, py::ssize_t columns)
{
    py::array_t<T> out({static_cast<py::ssize_t>(flat.size()) / columns, columns});
    std::copy(flat.begin(), flat.end(), out.mutable_data());
    return out;
}

template <class T, class U = T> py::array_t<T> array_1d(const std::vector<U>& values)
{
    py::array_t<T> out(static_cast<py::ssize_t>(values.size()));
    std::copy(values.begin(), values.end(), out.mutable_data());
    return out;
}

// What mesh_surface and mesh_gmsh_model return: the arrays as a read-only
// mapping, and the run behind them for the writers.
struct PyMeshResult {
    py::dict items;                     // the arrays and values, by name
    MeshResult run;                     // its arrays cleared (they are in `items`): MeshResult::run and
                                        // layers_built only
    std::optional<std::string> report;  // report_json, made on first use
};

// A path argument: str, bytes or os.PathLike.
std::filesystem::path path_argument(const py::handle& value)
{
    const py::object text = py::module_::import("os").attr("fsdecode")(value);
    return std::filesystem::path(text.cast<std::string>());
}

py::dict result_dict(const MeshResult& m)
{
    py::dict out;
    out["points"] = array_2d<double>(m.points, 3);
    out["tets"] = array_2d<std::int64_t>(std::vector<std::int64_t>(m.tets.begin(), m.tets.end()), 4);
    out["surface_points"] = m.surface_points;
    out["boundary_triangles"] = array_2d<std::int64_t>(
        std::vector<std::int64_t>(m.boundary_triangles.begin(), m.boundary_triangles.end()), 3);
    out["boundary_patch"] = array_1d<std::int32_t>(m.boundary_patch);
    out["patch_names"] = m.patch_names;
    out["D"] = array_1d<double>(m.D);
    out["D_out"] = array_1d<double>(m.D_out);
    out["d"] = array_1d<double>(m.d);
    out["layers"] = array_1d<double>(m.layers);
    out["point_layer"] = array_1d<std::int32_t>(m.point_layer);
    out["point_generator"] = array_1d<std::int32_t>(m.point_generator);
    out["point_filler"] = array_1d<bool>(m.point_filler);
    out["aspect_ratio"] = array_1d<double>(m.aspect_ratio);
    out["tet_layer"] = array_1d<std::int32_t>(m.tet_layer);
    return out;
}

// Any sequence or array of numbers, flattened (an (N, 3) array and a flat 3N
// list give the same).
std::vector<double> flat_doubles(const py::handle& values, const char* what)
{
    const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(values);
    if (!array) throw py::value_error(std::string(what) + " is not a sequence of numbers");
    return std::vector<double>(array.data(), array.data() + array.size());
}

std::vector<std::int64_t> flat_integers(const py::handle& values, const char* what)
{
    const py::array source = py::array::ensure(values);
    if (!source) throw py::value_error(std::string(what) + " is not a sequence of integers");
    if (source.size() > 0 && source.dtype().kind() != 'i' && source.dtype().kind() != 'u')
        throw py::value_error(std::string(what) + " holds " + std::string(py::str(source.dtype())) +
                              " values. Hint: give integers (point indices or Gmsh node tags)");
    const auto array = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(source);
    return std::vector<std::int64_t>(array.data(), array.data() + array.size());
}

PyMeshResult wrap(py::dict items, const MeshResult& mesh)
{
    PyMeshResult out;
    out.items = std::move(items);
    out.run.run = mesh.run;
    out.run.layers_built = mesh.layers_built;
    return out;
}

// The points and triangles of mesh_surface's first arguments: (points,
// triangles), a tuple (points, triangles) alone, or a meshio.Mesh (told by
// its points and cells, so that meshio is never imported here), whose
// "triangle" cell blocks are the surface; vertex and line blocks (Gmsh's
// points and curves) are left out, any other cell type is refused.
std::pair<py::object, py::object> surface_arrays(const py::handle& points, const py::handle& triangles)
{
    const bool meshio = py::hasattr(points, "points") && py::hasattr(points, "cells");
    if (!meshio) {
        if (!triangles.is_none()) return {py::reinterpret_borrow<py::object>(points),
                                          py::reinterpret_borrow<py::object>(triangles)};
        if (py::isinstance<py::tuple>(points) && py::len(points) == 2) {
            const py::tuple pair = points.cast<py::tuple>();
            return {pair[0], pair[1]};
        }
        throw py::type_error("mesh_surface needs the triangles. Hint: give mesh_surface(points, triangles), "
                             "mesh_surface((points, triangles)) or mesh_surface(meshio_mesh)");
    }
    if (!triangles.is_none())
        throw py::type_error("mesh_surface got a meshio.Mesh and triangles. Hint: give the mesh alone; its "
                             "\"triangle\" cells are the surface");
    const py::object xyz = points.attr("points");
    const py::array coordinates = py::array::ensure(xyz);
    if (!coordinates || coordinates.ndim() != 2 || coordinates.shape(1) != 3)
        throw py::value_error("the meshio.Mesh's points are not an (N, 3) array. Hint: give 3-D points in mm");
    py::list blocks;
    std::set<std::string> others;
    for (const py::handle block : points.attr("cells")) {
        // meshio's CellBlock: .type and .data (a (type, data) tuple in meshio 4).
        const bool named = py::hasattr(block, "type") && py::hasattr(block, "data");
        const std::string type = py::str(named ? py::object(block.attr("type")) : py::object(block[py::int_(0)]));
        const py::object data = named ? py::object(block.attr("data")) : py::object(block[py::int_(1)]);
        if (type == "triangle") blocks.append(data);
        else if (type != "vertex" && type != "line") others.insert(type);
    }
    if (!others.empty() || blocks.empty()) {
        std::string types;
        for (const std::string& t : others) types += (types.empty() ? "" : ", ") + t;
        throw py::value_error(blocks.empty() ? "the meshio.Mesh has no \"triangle\" cells" +
                                                   (types.empty() ? std::string() : " (it has " + types + ")") +
                                                   ". Hint: give a triangulated surface (for a volume mesh, its "
                                                   "boundary triangles)"
                                             : "the meshio.Mesh has " + types + " cells besides its triangles. "
                                               "Hint: give a surface of triangles only (split quads into "
                                               "triangles; for a volume mesh, its boundary triangles)");
    }
    return {xyz, py::module_::import("numpy").attr("concatenate")(blocks)};
}

PyMeshResult mesh_surface(const py::handle& points_or_mesh, const py::handle& triangles_or_none,
                          const py::handle& labels, const py::handle& node_tags, const py::handle& label_names,
                          const py::kwargs& kwargs)
{
    const MeshOptions options = mesh_options(kwargs);
    const auto [points, triangles] = surface_arrays(points_or_mesh, triangles_or_none);
    scalemesh::SurfaceInput surface;
    surface.points = flat_doubles(points, "points");
    const std::vector<std::int64_t> corners = flat_integers(triangles, "triangles");
    surface.triangles.reserve(corners.size());
    if (node_tags.is_none()) {
        for (std::int64_t c : corners) {
            if (c < 0)
                throw py::value_error("triangles hold a negative index (" + std::to_string(c) +
                                      "). Hint: give 0-based point indices, or Gmsh node tags with node_tags=");
            surface.triangles.push_back(static_cast<size_t>(c));
        }
    } else {
        // gmsh.model.mesh.getElementsByType gives node tags; getNodes gives
        // the tags of the points in their order.
        const std::vector<std::int64_t> tags = flat_integers(node_tags, "node_tags");
        if (tags.size() * 3 != surface.points.size())
            throw py::value_error("node_tags has " + std::to_string(tags.size()) + " tags for " +
                                  std::to_string(surface.points.size() / 3) +
                                  " points. Hint: pass the tags and coordinates of one gmsh.model.mesh.getNodes call");
        std::unordered_map<std::int64_t, size_t> index;
        index.reserve(tags.size());
        for (size_t i = 0; i < tags.size(); ++i)
            if (!index.emplace(tags[i], i).second)
                throw py::value_error("node tag " + std::to_string(tags[i]) + " appears twice in node_tags");
        for (std::int64_t c : corners) {
            const auto found = index.find(c);
            if (found == index.end())
                throw py::value_error("a triangle names node tag " + std::to_string(c) +
                                      ", which node_tags does not hold. Hint: get the nodes with "
                                      "gmsh.model.mesh.getNodes() (all entities, includeBoundary) so that every "
                                      "triangle's nodes are included");
            surface.triangles.push_back(found->second);
        }
    }
    if (!labels.is_none())
        for (std::int64_t label : flat_integers(labels, "labels")) {
            if (label < 0 || label > std::numeric_limits<std::int32_t>::max())
                throw py::value_error("labels hold " + std::to_string(label) + ". Hint: give labels 0, 1, 2, ...");
            surface.labels.push_back(static_cast<std::int32_t>(label));
        }
    if (!label_names.is_none()) surface.label_names = label_names.cast<std::vector<std::string>>();
    MeshResult result;
    {
        py::gil_scoped_release released;
        result = scalemesh::mesh_surface(surface, options);
    }
    return wrap(result_dict(result), result);
}

// Three numbers (or one, for all three axes) as a spacing or an origin.
std::array<double, 3> three_numbers(const char* what, const py::handle& value, const char* hint)
{
    const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
    if (array && array.ndim() == 0) return {array.data()[0], array.data()[0], array.data()[0]};
    if (!array || array.size() != 3)
        throw py::value_error(std::string(what) + " is not 3 numbers. Hint: " + hint);
    return {array.data()[0], array.data()[1], array.data()[2]};
}

// The voxel types of ImageView, by NumPy's kind and item size.
std::optional<scalemesh::ImageView::Type> voxel_type(char kind, py::ssize_t size)
{
    using T = scalemesh::ImageView::Type;
    if (kind == 'u' || kind == 'b') {
        if (size == 1) return T::uint8;
        if (size == 2) return T::uint16;
        if (size == 4) return T::uint32;
        if (size == 8) return T::uint64;
    } else if (kind == 'i') {
        if (size == 1) return T::int8;
        if (size == 2) return T::int16;
        if (size == 4) return T::int32;
        if (size == 8) return T::int64;
    } else if (kind == 'f') {
        if (size == 4) return T::float32;
        if (size == 8) return T::float64;
    }
    return std::nullopt;
}

// A NumPy array vol[i, j, k] as an ImageView of its own memory (copied only
// when its byte order is not the machine's or a stride is not a whole number
// of items); `keep` holds the array the view points into.
scalemesh::ImageView image_view(const py::handle& image, py::object& keep)
{
    py::array array = py::array::ensure(image);
    if (!array)
        throw py::type_error("image is neither a path nor an array. Hint: give a file path or a 3-D NumPy array "
                             "vol[i, j, k]");
    if (array.ndim() != 3) {
        const std::string shape = py::str(py::tuple(array.attr("shape")));
        throw py::value_error("the image array has " + std::to_string(array.ndim()) + " dimension" +
                              (array.ndim() == 1 ? "" : "s") + " (shape " + shape +
                              "); a 3-D volume vol[i, j, k] is needed. Hint: stack the slices into one 3-D array "
                              "(numpy.stack(slices, axis=2))");
    }
    const py::dtype dtype = array.dtype();
    const auto type = voxel_type(dtype.kind(), dtype.itemsize());
    if (!type)
        throw py::type_error("the image array holds " + dtype.attr("name").cast<std::string>() +
                             " values, which are not read. Hint: give bool, uint8, int8, uint16, int16, uint32, "
                             "int32, uint64, int64, float32 or float64 (e.g. vol.astype(numpy.float32))");
    if (!dtype.attr("isnative").cast<bool>()) array = array.attr("astype")(dtype.attr("newbyteorder")("="));
    // Read in place unless a stride is not a whole number of items, the
    // buffer is misaligned, or every stride is 0 (a broadcast scalar, which
    // ImageView would take for the packed layout): then a packed copy.
    bool copy = !array.attr("flags").attr("aligned").cast<bool>() ||
                (array.strides(0) == 0 && array.strides(1) == 0 && array.strides(2) == 0 && array.size() > 1);
    for (int d = 0; d < 3; ++d) copy = copy || array.strides(d) % array.itemsize() != 0;
    if (copy) array = py::module_::import("numpy").attr("ascontiguousarray")(array);
    scalemesh::ImageView view;
    view.data = array.data();
    view.type = *type;
    for (int d = 0; d < 3; ++d) {
        view.size[d] = array.shape(d);
        view.strides[d] = array.strides(d) / array.itemsize();
    }
    keep = array;
    return view;
}

// ImageOptions from mesh_image's keywords; the library checks them as the
// case reader checks [input] (ValueError naming the key).
scalemesh::ImageOptions image_options(const py::handle& labels, const py::handle& threshold, bool level_set,
                                      const py::handle& iso, int connectivity, const py::handle& grid,
                                      const std::string& units)
{
    scalemesh::ImageOptions how;
    if (!labels.is_none()) {
        const py::array values = py::array::ensure(labels);
        if (!values || (values.size() > 0 && values.dtype().kind() != 'i' && values.dtype().kind() != 'u'))
            throw py::type_error("labels is not an integer or a list of integers. Hint: give the label values "
                                 "that are inside, e.g. labels=[1] or labels=1");
        for (std::int64_t label : flat_integers(values, "labels")) {
            if (label < std::numeric_limits<int>::min() || label > std::numeric_limits<int>::max())
                throw py::value_error("labels hold " + std::to_string(label) + ", beyond a 32-bit label");
            how.labels.push_back(static_cast<int>(label));
        }
        if (how.labels.empty())
            throw py::value_error("labels is empty. Hint: give the label values that are inside, or None for "
                                  "every nonzero voxel");
    }
    if (!threshold.is_none()) how.threshold = checked_cast<double>("threshold", threshold, "a number");
    how.level_set = level_set;
    if (!iso.is_none()) how.iso = checked_cast<double>("iso", iso, "a number");
    how.connectivity = connectivity;
    if (!grid.is_none()) how.grid = checked_cast<std::string>("grid", grid, "a string (the grid's name)");
    how.units = units;
    return how;
}

PyMeshResult mesh_image(const py::handle& image, const py::handle& spacing, const py::handle& origin,
                        const py::handle& labels, const py::handle& threshold, bool level_set, const py::handle& iso,
                        int connectivity, const py::handle& grid, const std::string& units, const py::kwargs& kwargs)
{
    const MeshOptions options = mesh_options(kwargs);
    const scalemesh::ImageOptions how =
        image_options(labels, threshold, level_set, iso, connectivity, grid, units);
    MeshResult result;
    if (py::isinstance<py::str>(image) || py::isinstance<py::bytes>(image) ||
        py::hasattr(image, "__fspath__")) {
        if (!spacing.is_none() || !origin.is_none())
            throw py::value_error("spacing and origin are given for an image file, whose header holds them. Hint: "
                                  "give them only with an array");
        const std::filesystem::path path = path_argument(image);
        py::gil_scoped_release released;
        result = scalemesh::mesh_image(path, options, how);
    } else {
        py::object keep;
        scalemesh::ImageView view = image_view(image, keep);
        if (spacing.is_none())
            throw py::value_error("an image array needs its spacing. Hint: give spacing=(sx, sy, sz), the distance "
                                  "between voxel centres along i, j, k in mm");
        view.spacing = three_numbers("spacing", spacing, "give spacing=(sx, sy, sz) in mm");
        if (!origin.is_none())
            view.origin = three_numbers("origin", origin, "give origin=(ox, oy, oz), the centre of vol[0, 0, 0] in mm");
        // The array stays referenced (keep) and unchanged by this thread while the run reads it.
        py::gil_scoped_release released;
        result = scalemesh::mesh_image(view, options, how);
    }
    return wrap(result_dict(result), result);
}

PyMeshResult mesh_gmsh_model(const py::handle& physical_group, const std::string& volume_name, bool views,
                         const py::kwargs& kwargs)
{
    const MeshOptions options = mesh_options(kwargs);
    scalemesh::GmshModelOptions model;
    if (!physical_group.is_none()) model.physical_group = physical_group.cast<std::string>();
    model.volume_name = volume_name;
    model.views = views;
    scalemesh::GmshModelResult result;
    {
        py::gil_scoped_release released;
        result = scalemesh::mesh_gmsh_model(model, options);
    }
    py::dict out = result_dict(result.mesh);
    out["volume"] = result.volume;
    out["patch_surfaces"] = result.patch_surfaces;
    out["volume_group"] = result.volume_group;
    out["patch_groups"] = result.patch_groups;
    out["first_node_tag"] = result.first_node_tag;
    out["first_tet_tag"] = result.first_tet_tag;
    out["views"] = result.views;
    out["removed_volumes"] = result.removed_volumes;
    return wrap(out, result.mesh);
}

py::dict openfoam_case_dict(const scalemesh::OpenFoamCase& c)
{
    py::dict out;
    out["cells"] = c.cells;
    out["faces"] = c.faces;
    out["internal_faces"] = c.internal_faces;
    out["layer_prisms"] = c.layer_prisms;
    out["patch_names"] = c.patch_names;
    out["patch_faces"] = c.patch_faces;
    out["flow_fields"] = c.flow_fields;
    out["warnings"] = c.warnings;
    return out;
}

const std::string& report_text(PyMeshResult& r)
{
    if (!r.report) {
        std::string text;
        {
            py::gil_scoped_release released;
            text = scalemesh::report_json(r.run);
        }
        r.report = std::move(text);
    }
    return *r.report;
}

py::list list_of(const py::object& a, const py::object& b)
{
    py::list out;
    out.append(a);
    out.append(b);
    return out;
}

// meshio.Mesh of the result: the tets and the boundary triangles as two
// cell blocks, the point fields as point data, per cell the patch (-1 on
// tets) and the aspect ratio (NaN on triangles), and the patch names as
// field data in Gmsh's convention (name: [tag, dimension]).
py::object to_meshio(const PyMeshResult& r)
{
    py::module_ meshio;
    try {
        meshio = py::module_::import("meshio");
    } catch (py::error_already_set& e) {
        if (!e.matches(PyExc_ImportError)) throw;
        throw py::import_error("to_meshio needs the meshio package. Hint: install it (Debian: apt-get install "
                               "python3-meshio; or pip install meshio)");
    }
    const py::module_ np = py::module_::import("numpy");
    const py::dict& m = r.items;
    const size_t tets = py::len(m["tets"]), triangles = py::len(m["boundary_triangles"]);
    py::list cells;
    cells.append(py::make_tuple("tetra", m["tets"]));
    cells.append(py::make_tuple("triangle", m["boundary_triangles"]));
    py::dict point_data;
    for (const char* name : {"D", "D_out", "d", "layers", "point_layer"}) point_data[name] = m[name];
    py::dict cell_data;
    cell_data["patch"] = list_of(np.attr("full")(tets, -1, "dtype"_a = "int32"), m["boundary_patch"]);
    cell_data["aspect_ratio"] =
        list_of(m["aspect_ratio"], np.attr("full")(triangles, std::numeric_limits<double>::quiet_NaN()));
    py::dict field_data;
    const py::list names = m["patch_names"];
    for (size_t p = 0; p < py::len(names); ++p)
        field_data[names[p]] = np.attr("array")(py::make_tuple(p, 2));
    return meshio.attr("Mesh")(m["points"], cells, "point_data"_a = point_data, "cell_data"_a = cell_data,
                               "field_data"_a = field_data);
}

} // namespace

PYBIND11_MODULE(scalemesh, m)
{
    m.doc() = R"(scalemesh: layered tetrahedral meshes for CFD from surfaces and images.

mesh_surface(points, triangles, labels=None, *, node_tags=None, label_names=None, **options)
mesh_surface(meshio_mesh, **options)
mesh_image(path_or_array, spacing=None, origin=None, labels=None, *, threshold=None, level_set=False,
           iso=None, connectivity=6, grid=None, units="mm", **options)
mesh_gmsh_model(physical_group=None, *, volume_name="fluid", views=True, **options)

Each returns a MeshResult: a read-only mapping of NumPy arrays (result["points"],
...), with write_openfoam(case_dir), write_msh(path), report and to_meshio().

Options (keyword arguments; their defaults, those of the case file
scalemesh.toml too, are defaults()):
)" + options_doc() + R"(  openings, progress, gmsh_session: see below.
Lengths are numbers in mm or strings "2 mm" / "0.5 voxels". progress(stage, seconds,
summary) is called when a stage starts (seconds < 0) and ends. openings is a
list of dicts with the keys of the case file's [[openings]] tables (name,
type, point, normal, radius, border, inset, near, label, extension), e.g.
{"name": "inlet", "type": "inlet", "near": [0, 0, -15]} for an open end.
gmsh_session=True when gmsh.py is initialised (gmsh.initialize()): reading
a .msh input and the core of layers="prisms" go through that session, the
current model and options left as they were; with the default False the
library initialises and finalises Gmsh around them, which would end a
gmsh.py session (mesh_gmsh_model always works in the gmsh.py session).

Errors: ValueError (bad input or options: the message says what to change),
RuntimeError (a stage failed), OSError (a file).)";

    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const scalemesh::InputError& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        } catch (const scalemesh::IoError& e) {
            PyErr_SetString(PyExc_OSError, e.what());
        } catch (const scalemesh::StageError& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        }
    });

    py::class_<PyMeshResult> result(m, "MeshResult", R"(The layered tetrahedral mesh (mm) and the run that made it.

A read-only mapping of NumPy arrays, as the dicts mesh_surface and
mesh_gmsh_model returned before: result["points"], result.keys(), dict(result).
The methods write what `scalemesh run` writes, by the same writers, from the
run behind the arrays (changing an array changes nothing they write).)");
    result.def("__getitem__",
               [](const PyMeshResult& r, const py::object& key) -> py::object {
                   if (!r.items.contains(key)) throw py::key_error(py::repr(key).cast<std::string>());
                   return r.items[key];
               })
        .def("__contains__", [](const PyMeshResult& r, const py::object& key) { return r.items.contains(key); })
        .def("__iter__", [](const PyMeshResult& r) { return py::iter(r.items); })
        .def("__len__", [](const PyMeshResult& r) { return py::len(r.items); })
        .def("keys", [](const PyMeshResult& r) { return r.items.attr("keys")(); })
        .def("values", [](const PyMeshResult& r) { return r.items.attr("values")(); })
        .def("items", [](const PyMeshResult& r) { return r.items.attr("items")(); })
        .def("get", [](const PyMeshResult& r, const py::object& key, const py::object& fallback) {
                 return r.items.contains(key) ? py::object(r.items[key]) : fallback;
             }, py::arg("key"), py::arg("default") = py::none())
        .def("__repr__", [](const PyMeshResult& r) {
            return "<scalemesh.MeshResult: " + std::to_string(py::len(r.items["points"])) + " points, " +
                   std::to_string(py::len(r.items["tets"])) + " tets, patches " +
                   py::repr(r.items["patch_names"]).cast<std::string>() + ">";
        })
        .def_property_readonly("report", [](PyMeshResult& r) {
            return py::module_::import("json").attr("loads")(report_text(r));
        }, R"(The run's report as a dict: what report.json of `scalemesh run` holds for a run that wrote
no files (stages, surface facts, sizing, remeshing, volume quality, layers, openings, warnings).)")
        .def_property_readonly("layers_built", [](const PyMeshResult& r) { return r.run.layers_built; },
                               R"(The layers the run built, as report.json's volume.layers_built: "prisms" or
"delaunay". The layers option, but for prism layers given up because their mesh missed a
floor: then "delaunay", and report["volume"]["layer_fallback"] says why.)")
        .def("report_json", [](PyMeshResult& r) { return report_text(r); },
             "The report as report.json's JSON text.")
        .def("write_openfoam",
             [](PyMeshResult& r, const py::object& case_dir, double viscosity, double inlet_speed, bool binary,
                bool layer_prisms) {
                 const std::filesystem::path dir = path_argument(case_dir);
                 scalemesh::OpenFoamCase written;
                 {
                     py::gil_scoped_release released;
                     written = scalemesh::write_openfoam(r.run, dir, {.viscosity = viscosity,
                                                                      .inlet_speed = inlet_speed,
                                                                      .binary = binary,
                                                                      .layer_prisms = layer_prisms});
                 }
                 return openfoam_case_dict(written);
             },
             py::arg("case_dir"), py::kw_only(), py::arg("viscosity") = scalemesh::OpenFoamOptions{}.viscosity,
             py::arg("inlet_speed") = scalemesh::OpenFoamOptions{}.inlet_speed,
             py::arg("binary") = scalemesh::OpenFoamOptions{}.binary,
             py::arg("layer_prisms") = scalemesh::OpenFoamOptions{}.layer_prisms,
             R"(Writes the OpenFOAM case into case_dir (made if missing) as `scalemesh run` writes it.

constant/polyMesh (metres; the layer prisms as prism cells where OpenFOAM's
cell checks pass them; patch "wall" and one per opening), constant/ and
system/ for simpleFoam, 0/U and 0/p when there are an inlet and an outlet,
Allrun (checkMesh, then simpleFoam) and report.json. All files appear
together or none. viscosity (m^2/s) and inlet_speed (m/s) are the case
file's [flow]; binary and layer_prisms its [output] openfoam_format and
layer_prisms. Returns a dict: cells, faces, internal_faces, layer_prisms,
patch_names, patch_faces, flow_fields, warnings.)")
        .def("write_msh",
             [](PyMeshResult& r, const py::object& path, double version, bool binary, bool gmsh_session) {
                 const std::filesystem::path file = path_argument(path);
                 py::gil_scoped_release released;
                 scalemesh::write_msh(r.run, file,
                                      {.version = version, .binary = binary, .host_gmsh_session = gmsh_session});
             },
             py::arg("path"), py::kw_only(), py::arg("version") = scalemesh::MshOptions{}.version,
             py::arg("binary") = scalemesh::MshOptions{}.binary, py::arg("gmsh_session") = false,
             R"(Writes the volume mesh to path (.msh) as `scalemesh run` writes mesh.msh.

Physical volume "fluid", a physical surface per patch, the views D, D_out, d,
edge_length_ratio, layers, aspect_ratio and layer, version 4.1 or 2.2.
gmsh_session=True when gmsh.py is initialised (gmsh.initialize()): the file is
written through that session and the current model and options are left as
they were. With the default False the library initialises and finalises Gmsh
around the write, which would end a gmsh.py session.)")
        .def("to_meshio", &to_meshio,
             R"(The mesh as a meshio.Mesh (needs the meshio package): cell blocks "tetra" and "triangle"
(the boundary), point data D, D_out, d, layers, point_layer, cell data patch
(-1 on tets) and aspect_ratio (NaN on triangles), field data {patch name:
[patch id, 2]}.)");
    py::module_::import("collections.abc").attr("Mapping").attr("register")(result);

    m.def("mesh_surface", &mesh_surface, py::arg("points"), py::arg("triangles") = py::none(),
          py::arg("labels") = py::none(),
          py::kw_only(), py::arg("node_tags") = py::none(), py::arg("label_names") = py::none(),
          R"(Meshes a triangulated surface (mm) as `scalemesh run` meshes a surface file.

The surface is closed and 2-manifold, or open-ended (a 2-manifold whose open
loops are vessel ends): each open end is cut flat, capped and becomes an
opening, named by openings=[{"name": ..., "type": ..., "near": [x, y, z]}]
or else "inlet" (the largest) and outlet_1, outlet_2, ...

points: (N, 3) or flat 3N coordinates, or a meshio.Mesh (its "triangle" cells
are the surface; vertex and line cells are left out, other cells refused), or
a tuple (points, triangles), with triangles then left out. triangles: (M, 3) or flat 3M 0-based
indices into points, or, with node_tags, Gmsh node tags (the layout of
gmsh.model.mesh.getNodes and getElementsByType(2): node_tags are the tags of
the points in order, triangles hold tags). labels: one integer per triangle,
or None; each boundary triangle gets the label of the nearest input triangle
as its patch id; label_names[i] names label i (else "patch_<i>"); a closed
surface without openings only (they are walls in write_openfoam).

Returns a MeshResult, a mapping of NumPy arrays: points (N, 3), tets (T, 4) positively
oriented, boundary_triangles (B, 3) counter-clockwise seen from outside,
boundary_patch (B,), patch_names (list), surface_points (the boundary nodes
are points[:surface_points]), D, D_out, d, layers (N,) (NaN at interior
points), point_layer (N,), point_generator (N,) (the boundary node each point
was made from), point_filler (N,) (True for filler and edge-split points; the
column of boundary node i is the points with generator i and not filler, in
the order of point_layer), aspect_ratio (T,), tet_layer (T,).)");

    m.def("mesh_image", &mesh_image, py::arg("image"), py::arg("spacing") = py::none(),
          py::arg("origin") = py::none(), py::arg("labels") = py::none(), py::kw_only(),
          py::arg("threshold") = py::none(), py::arg("level_set") = false, py::arg("iso") = py::none(),
          py::arg("connectivity") = scalemesh::ImageOptions{}.connectivity, py::arg("grid") = py::none(),
          py::arg("units") = scalemesh::ImageOptions{}.units,
          R"(Meshes an image, a file or a NumPy array, as `scalemesh run` meshes an image file.

image: a path (.vdb, .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd, .vti, or a
surface file .stl, .ply, .obj, .vtp, .msh), or a 3-D array vol[i, j, k]
(pygalmesh's generate_from_array convention) of bool, uint8, int8, uint16,
int16, uint32, int32, uint64, int64, float32 or float64, whose voxel (i, j, k)
is centred at origin + (i * spacing[0], j * spacing[1], k * spacing[2]) mm:
the first index runs along x, the last along z, whatever the array's memory
order (C or Fortran order, or any strides; the voxels are read in place).
The array meshes exactly as a MetaImage holding the same voxels with
Offset = origin and ElementSpacing = spacing would.

spacing: (sx, sy, sz) in mm (or one number for all three), needed with an
array; origin: (ox, oy, oz) in mm, default (0, 0, 0); a file's header holds
both. How voxels become inside, as the case file's [input]: labels (an
integer or a list: those values are inside), threshold (inside where value >
threshold), level_set=True (a signed distance, negative inside), or, with none
of them, every nonzero voxel; iso (default 0.5, 0 for level sets),
connectivity (6 or 26). grid (a .vdb's grid) and units (a surface file's) are
for files only. Options (openings, K, M, ...) as mesh_surface's.

Returns a MeshResult as mesh_surface's.)");

    m.def("mesh_gmsh_model", &mesh_gmsh_model, py::arg("physical_group") = py::none(), py::kw_only(),
          py::arg("volume_name") = "fluid", py::arg("views") = true,
          R"(Meshes the surface of the current gmsh.py model and adds the volume mesh to it.

The gmsh module must be initialised (gmsh.initialize()) and the model meshed
in 2D. Meshes every surface entity, or those of the physical surface named
physical_group; surface entities in a physical surface not named "wall"
become patches of that name, the rest "wall". Adds one discrete surface per
patch, a discrete volume bounded by them holding the tets, a physical volume
volume_name, a physical surface per patch, and (views=True) the views D,
D_out, d, layers (NodeData) and aspect_ratio (ElementData). Never calls
gmsh.initialize or gmsh.finalize.

Returns the MeshResult of mesh_surface, whose mapping also holds volume (entity tag), patch_surfaces and
patch_groups (per patch id: entity and physical group tags, -1 for a patch
without triangles), volume_group, first_node_tag and first_tet_tag (point i
is node first_node_tag + i, tet t element first_tet_tag + t), views (tags),
removed_volumes (the input volume entities removed from the model, so that a
later gmsh.model.mesh.generate(3) does not mesh them on top of the result).)");

    m.def("defaults", [] {
        const MeshOptions o;
        py::dict d;
        for (const scalemesh::OptionInfo& option : scalemesh::mesh_option_table())
            d[py::str(option.keyword)] = option_value(o, option);
        return d;
    }, "The default options: those of the case file scalemesh.toml.");
}
