#pragma once
// The meshing options, described once (issue 44): for each, its case-file
// section and key, its Python keyword, its kind, range or choices, unit and a
// line of documentation, and the MeshOptions member it reads and writes. The
// case reader (parse_case), the library (config_from_options), the Python
// keywords and `scalemesh options --json` (which the Gmsh GUI client reads)
// all iterate this table. The defaults are not in it: they are MeshOptions{}'s
// (include/scalemesh/mesh.h), the one place they are set.
//
// This header includes no core/errors.h, so that the Python module (which
// sees the installed scalemesh/errors.h) can include it too.

#include "scalemesh/mesh.h"

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace scalemesh {

enum class OptionKind {
    number,  // a real number
    integer, // a whole number
    boolean, // true or false
    choice,  // one of `choices`
    length,  // mm or voxel widths: a number (mm) or "1.5 mm", "2 voxels"; always positive
};

// The MeshOptions member an option is.
using OptionMember =
    std::variant<double MeshOptions::*, int MeshOptions::*, std::int64_t MeshOptions::*, bool MeshOptions::*,
                 std::string MeshOptions::*, MeshLength MeshOptions::*, std::optional<MeshLength> MeshOptions::*>;

struct OptionInfo {
    std::string section = {}; // the case file's section, e.g. "sizing"; empty: no case-file key (library, Python)
    std::string key = {};     // the case file's key in that section
    std::string keyword = {}; // the Python keyword, the name of the MeshOptions member
    OptionKind kind = {};
    OptionMember member = {};
    // number and integer: the range [min, max], or (min, max] with min_open.
    double min = 0;
    double max = 0;
    bool min_open = false;
    std::vector<std::string> choices = {}; // choice: the valid values
    std::string what = {};            // choice: what a valid value is, for "... is not <what>"
    std::string hint = {};            // what to do when the value is refused; empty: the range or the choices
    std::string unit = {};            // e.g. "mm or voxels", "degrees"; empty: dimensionless
    std::string doc = {};             // one line
};

// Every meshing option, in the case file's order of sections.
const std::vector<OptionInfo>& mesh_option_table();

// The option of the Python keyword (MeshOptions member) `keyword`, or null.
const OptionInfo* find_option(const std::string& keyword);

// "number", "integer", "boolean", "choice" or "length".
const char* option_kind_name(OptionKind kind);

// A number as messages and the case file write it: the shortest text that
// reads back as `v`, whatever the process's locale ("0.5", "1e-09", "3").
std::string number_text(double v);

// An interval as the messages write it: "[lo, hi]", "(lo, hi]" with lo_open.
std::string interval_text(double lo, double hi, bool lo_open);

// The option's range as the messages write it, e.g. "(0, 1000]".
std::string range_text(const OptionInfo& option);

// The table as JSON (`scalemesh options --json`): an array of objects with
// section, key, keyword, kind, default (MeshOptions{}'s; null for an empty
// L_max; a length as "0.5 voxels" or a number of mm), min, max, min_open,
// choices, unit and doc.
std::string mesh_options_json();

// The table for a reader (`scalemesh options`): a line per option, e.g.
// "[sizing] K = 4.2  number in (0, 1000]: anisotropy of ...".
std::string mesh_options_text();

} // namespace scalemesh
