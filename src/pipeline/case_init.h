#pragma once
// `scalemesh init DIR FILE`: a first case file for an image or a surface,
// written from what the file holds, so that a new user starts from a case
// that runs rather than from an empty page.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

struct InitialCase {
    std::string text;                // scalemesh.toml, commented
    std::vector<std::string> notes;  // one line each, for the terminal: what was found and chosen
};

// Inspects `file` (an image or a surface scalemesh reads) as a case in `dir`
// would read it, and writes the case file for it:
//   - [input] file, as a path relative to `dir` where one exists;
//   - an image: how its voxels become inside, from its values (a label map:
//     every nonzero label, the labels present listed; an intensity image: a
//     threshold halfway through its range; negative and positive values that
//     are not integers: a level set), and a border opening on each image side
//     the segmentation touches, the side with the largest contact the inlet;
//   - a surface: units, where the coordinates are implausible in mm; the
//     open ends and labelled caps found, which become openings by themselves,
//     and the face labels with what each became;
//   - the defaults of every other section, commented out.
// The case is read and run up to its openings before it is returned, so what
// it names exists; openings that fail there are left commented out, with
// the reason as a note. `max_memory` bounds the import (0: the machine's).
// Throws IoError for a missing file and InputError for one scalemesh cannot
// read, as `scalemesh run` would.
InitialCase initial_case(const std::filesystem::path& file, const std::filesystem::path& dir, int64_t max_memory = 0);

} // namespace scalemesh
