#pragma once
// The paper's Fig. 19 as a picture: binned tetrahedron aspect ratios, one bar
// colour per stage of mesh improvement, written as a PNG (libpng).

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

struct HistogramSeries {
    std::string label;            // legend text, e.g. "before flips"
    std::vector<int64_t> counts;  // tets per bin; bin k covers [k/n, (k+1)/n) of the aspect ratio
};

struct HistogramPngOptions {
    int width = 900;   // pixels
    int height = 540;  // pixels
    std::string title = "aspect ratio 2 sqrt(6) r_in / l_max";
};

// Draws the series as grouped bars over aspect ratio 0 to 1 (every series has
// the same number of bins), counts on a log10(1 + count) axis so that a few
// slivers stay visible next to thousands of good tets, with axes, tick labels
// and a legend, on a white background. Writes `path` directly (callers that
// need atomicity pass a temporary name). Throws InputError when there are no
// series, the series differ in bin count or have none, or a size is outside
// [200, 8000] pixels; IoError when the file cannot be written.
void write_histogram_png(const std::vector<HistogramSeries>& series, const std::filesystem::path& path,
                         const HistogramPngOptions& options = {});

} // namespace scalemesh
