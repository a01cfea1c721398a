// The Python module `scalemesh` (pybind11): mesh_surface on NumPy arrays or
// flat sequences in gmsh.py's layout, and mesh_gmsh_model on the current
// model of the gmsh.py session, which shares this process's libgmsh with the
// library (src/python/CMakeLists.txt). Results are dicts of NumPy arrays.
// Errors: InputError -> ValueError, StageError -> RuntimeError,
// IoError -> OSError, with the library's message.

#include "scalemesh/scalemesh.h"

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <unordered_map>

namespace py = pybind11;

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

const char* const option_names[] = {"K", "M", "G", "L_min", "L_max", "curvature", "smoothing_sweeps",
                                    "smoothing_omega", "smoothing_reach", "remesh_cycles", "growth", "first_layer",
                                    "layers", "layer_tolerance", "threads", "max_memory", "progress"};

// MeshOptions from keyword arguments named as its members; the library
// checks the values (ValueError naming the key).
MeshOptions mesh_options(const py::kwargs& kwargs)
{
    MeshOptions o;
    for (const auto& [key_handle, value] : kwargs) {
        const std::string key = key_handle.cast<std::string>();
        if (key == "K") o.K = value.cast<double>();
        else if (key == "M") o.M = value.cast<double>();
        else if (key == "G") o.G = value.cast<double>();
        else if (key == "L_min") o.L_min = length_option("L_min", value);
        else if (key == "L_max") {
            if (value.is_none()) o.L_max.reset();
            else o.L_max = length_option("L_max", value);
        } else if (key == "curvature") o.curvature = value.cast<bool>();
        else if (key == "smoothing_sweeps") o.smoothing_sweeps = value.cast<int>();
        else if (key == "smoothing_omega") o.smoothing_omega = value.cast<double>();
        else if (key == "smoothing_reach") o.smoothing_reach = length_option("smoothing_reach", value);
        else if (key == "remesh_cycles") o.remesh_cycles = value.cast<int>();
        else if (key == "growth") o.growth = value.cast<double>();
        else if (key == "first_layer") o.first_layer = value.cast<std::string>();
        else if (key == "layers") o.layers = value.cast<std::string>();
        else if (key == "layer_tolerance") o.layer_tolerance = value.cast<double>();
        else if (key == "threads") o.threads = value.cast<int>();
        else if (key == "max_memory") o.max_memory = value.cast<std::int64_t>();
        else if (key == "progress") {
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
            for (const char* name : option_names) names += std::string(names.empty() ? "" : ", ") + name;
            throw py::type_error("unexpected keyword argument '" + key + "'; the options are: " + names);
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

py::dict mesh_surface(const py::handle& points, const py::handle& triangles, const py::handle& labels,
                      const py::handle& node_tags, const py::handle& label_names, const py::kwargs& kwargs)
{
    const MeshOptions options = mesh_options(kwargs);
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
    return result_dict(result);
}

py::dict mesh_gmsh_model(const py::handle& physical_group, const std::string& volume_name, bool views,
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
    return out;
}

} // namespace

PYBIND11_MODULE(scalemesh, m)
{
    m.doc() = R"(scalemesh: layered tetrahedral meshes for CFD from closed surfaces.

mesh_surface(points, triangles, labels=None, *, node_tags=None, label_names=None, **options)
mesh_gmsh_model(physical_group=None, *, volume_name="fluid", views=True, **options)

Options (keyword arguments, defaults those of the case file scalemesh.toml,
see defaults()): K, M, G, L_min, L_max, curvature, smoothing_sweeps,
smoothing_omega, smoothing_reach, remesh_cycles, growth, first_layer,
layers, layer_tolerance, threads, max_memory, progress. Lengths are numbers in mm or
strings "2 mm" / "0.5 voxels". progress(stage, seconds, summary) is called
when a stage starts (seconds < 0) and ends.

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

    m.def("mesh_surface", &mesh_surface, py::arg("points"), py::arg("triangles"), py::arg("labels") = py::none(),
          py::kw_only(), py::arg("node_tags") = py::none(), py::arg("label_names") = py::none(),
          R"(Meshes a closed, 2-manifold triangulated surface (mm) as `scalemesh run` meshes a surface file.

points: (N, 3) or flat 3N coordinates. triangles: (M, 3) or flat 3M 0-based
indices into points, or, with node_tags, Gmsh node tags (the layout of
gmsh.model.mesh.getNodes and getElementsByType(2): node_tags are the tags of
the points in order, triangles hold tags). labels: one integer per triangle,
or None; each boundary triangle gets the label of the nearest input triangle
as its patch id; label_names[i] names label i (else "patch_<i>").

Returns a dict of NumPy arrays: points (N, 3), tets (T, 4) positively
oriented, boundary_triangles (B, 3) counter-clockwise seen from outside,
boundary_patch (B,), patch_names (list), surface_points (the boundary nodes
are points[:surface_points]), D, D_out, d, layers (N,) (NaN at interior
points), point_layer (N,), point_generator (N,) (the boundary node each point
was made from), point_filler (N,) (True for filler and edge-split points; the
column of boundary node i is the points with generator i and not filler, in
the order of point_layer), aspect_ratio (T,), tet_layer (T,).)");

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

Returns the dict of mesh_surface plus volume (entity tag), patch_surfaces and
patch_groups (per patch id: entity and physical group tags, -1 for a patch
without triangles), volume_group, first_node_tag and first_tet_tag (point i
is node first_node_tag + i, tet t element first_tet_tag + t), views (tags),
removed_volumes (the input volume entities removed from the model, so that a
later gmsh.model.mesh.generate(3) does not mesh them on top of the result).)");

    m.def("defaults", [] {
        const MeshOptions o;
        py::dict d;
        d["K"] = o.K;
        d["M"] = o.M;
        d["G"] = o.G;
        const auto length = [](const MeshLength& l) {
            return l.voxels ? py::object(py::str(py::repr(py::float_(l.value)).cast<std::string>() + " voxels"))
                            : py::object(py::float_(l.value));
        };
        d["L_min"] = length(o.L_min);
        d["L_max"] = o.L_max ? length(*o.L_max) : py::object(py::none());
        d["curvature"] = o.curvature;
        d["smoothing_sweeps"] = o.smoothing_sweeps;
        d["smoothing_omega"] = o.smoothing_omega;
        d["smoothing_reach"] = length(o.smoothing_reach);
        d["remesh_cycles"] = o.remesh_cycles;
        d["growth"] = o.growth;
        d["first_layer"] = o.first_layer;
        d["layers"] = o.layers;
        d["layer_tolerance"] = o.layer_tolerance;
        d["threads"] = o.threads;
        d["max_memory"] = o.max_memory;
        return d;
    }, "The default options: those of the case file scalemesh.toml.");
}
