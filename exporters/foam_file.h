#pragma once
// An OpenFOAM file as the exporters write it: under a temporary name
// (AtomicOutput) until committed with the other outputs of its case, the
// FoamFile header at the top and OpenFOAM's closing comment line at the end.

#include "core/atomic_file.h"

#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace scalemesh {

// The FoamFile header of an OpenFOAM file: "binary" or "ascii" format, its
// class, location (e.g. "constant/polyMesh") and object, and a note when
// not empty.
std::string foam_file_header(bool binary, const std::string& cls, const std::string& location,
                             const std::string& object, const std::string& note = "");

// One file written in pieces, for files too large to hold whole (the
// polyMesh of a large mesh): the caller writes the header and the body with
// text(), then finish() adds the closing line.
class FoamFileOutput {
public:
    // The file's temporary name is opened, its directories made, and the
    // AtomicOutput appended to `outputs` for the caller to commit. Throws
    // IoError.
    FoamFileOutput(const std::filesystem::path& path, StagedOutputs& outputs);

    void text(std::string_view s) { out_.write(s.data(), static_cast<std::streamsize>(s.size())); }

    // The closing line, then the flush. Throws IoError when the file could
    // not be written.
    void finish();

private:
    std::filesystem::path path_;
    std::ofstream out_;
};

// A file held whole: `text`, its header included, then the closing line.
// Throws IoError.
void write_foam_file(const std::filesystem::path& path, std::string_view text, StagedOutputs& outputs);

} // namespace scalemesh
