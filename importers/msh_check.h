#pragma once
// Checking a Gmsh MSH file before Gmsh reads it. Internal to importers/.

#include <filesystem>
#include <string_view>

namespace scalemesh {

// Gmsh 4.8's MSH readers trust what a file says: its MSH4 reader looks node
// tags up as int, so an element naming a tag beyond int, or one no $Nodes
// entry defines, reads out of bounds (a segfault found by fuzzing), and counts
// size arrays before anything is read. This walks the file the way Gmsh will
// (MSH 2.2 and 4.1, ASCII and binary) without keeping the mesh, and throws
// InputError naming `path` at the first thing that does not fit: a version
// other than 2.2 or 4.1, a section without its end line, a count larger than
// the rest of the file holds or different from the items that follow, a tag
// of 0, above 2^31 - 1 or defined twice, an element type other than Gmsh's
// types 1 to 31 or in an entity of another dimension, an element node that
// the $Nodes section does not define, data on an undefined node or element,
// a line Gmsh would split, or a section Gmsh would read but scalemesh does not
// take (partitions, periodic links, ghost elements, parametrizations).
void check_msh_file(std::string_view bytes, const std::filesystem::path& path);

} // namespace scalemesh
