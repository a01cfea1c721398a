#pragma once
// `scalemesh run CASE_DIR`: the stages a case asks for, then its outputs and
// report.json written into the case directory, each file atomically.

#include "pipeline/surface_pipeline.h"

#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

struct CaseResult {
    SurfaceRun run;
    std::vector<std::filesystem::path> written; // in the order written, report.json last
};

// Throws InputError, IoError or StageError; a case that fails writes nothing.
CaseResult run_case(const std::filesystem::path& dir, const StageListener& listener = {});

// report.json of a run: version, input and its checksum, parameters, stage
// times, surface facts, sizing statistics and the files written.
std::string report_json(const CaseConfig& config, const SurfaceRun& run,
                        const std::vector<std::filesystem::path>& written);

// Writes `text` to `path` atomically. Throws IoError.
void write_text_file(const std::filesystem::path& path, const std::string& text);

} // namespace scalemesh
