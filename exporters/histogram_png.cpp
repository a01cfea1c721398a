#include "exporters/histogram_png.h"

#include "core/errors.h"

#include <png.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace scalemesh {

namespace {

using Rgb = std::array<uint8_t, 3>;

constexpr Rgb kWhite{255, 255, 255};
constexpr Rgb kBlack{0, 0, 0};
constexpr Rgb kGrid{225, 225, 225};
// Light to dark in the order of improvement, readable in grey print too.
constexpr std::array<Rgb, 6> kPalette{{{170, 170, 170}, {67, 138, 209}, {214, 96, 33}, {60, 160, 90}, {140, 80, 170}, {90, 90, 90}}};

// A 5x7 bitmap font, rows top to bottom, for the characters the chart writes;
// letters are drawn in upper case.
struct Glyph {
    char c;
    const char* rows; // 35 characters, '#' set
};
constexpr Glyph kFont[] = {
    {'A', ".###.#...##...#######...##...##...#"}, {'B', "####.#...##...#####.#...##...#####."},
    {'C', ".###.#...##....#....#....#...#.###."}, {'D', "####.#...##...##...##...##...#####."},
    {'E', "######....#....####.#....#....#####"}, {'F', "######....#....####.#....#....#...."},
    {'G', ".###.#...##....#.####...##...#.####"}, {'H', "#...##...##...#######...##...##...#"},
    {'I', ".###...#....#....#....#....#...###."}, {'J', "..###...#....#....#....#.#..#..##.."},
    {'K', "#...##..#.#.#..##...#.#..#..#.#...#"}, {'L', "#....#....#....#....#....#....#####"},
    {'M', "#...###.###.#.##.#.##...##...##...#"}, {'N', "#...##...###..##.#.##..###...##...#"},
    {'O', ".###.#...##...##...##...##...#.###."}, {'P', "####.#...##...#####.#....#....#...."},
    {'Q', ".###.#...##...##...##.#.##..#..##.#"}, {'R', "####.#...##...#####.#.#..#..#.#...#"},
    {'S', ".#####....#.....###.....#....#####."}, {'T', "#####..#....#....#....#....#....#.."},
    {'U', "#...##...##...##...##...##...#.###."}, {'V', "#...##...##...##...##...#.#.#...#.."},
    {'W', "#...##...##...##.#.##.#.##.#.#.#.#."}, {'X', "#...##...#.#.#...#...#.#.#...##...#"},
    {'Y', "#...##...#.#.#...#....#....#....#.."}, {'Z', "#####....#...#...#...#...#....#####"},
    {'0', ".###.#...##..###.#.###..##...#.###."}, {'1', "..#...##....#....#....#....#...###."},
    {'2', ".###.#...#....#...#...#...#...#####"}, {'3', "####.....#....#.###.....#....#####."},
    {'4', "...#...##..#.#.#..#.#####...#....#."}, {'5', "######....####.....#....##...#.###."},
    {'6', "..##..#...#....####.#...##...#.###."}, {'7', "#####....#...#...#...#....#....#..."},
    {'8', ".###.#...##...#.###.#...##...#.###."}, {'9', ".###.#...##...#.####....#...#..##.."},
    {'.', ".........................##....##.."}, {'(', "...#...#...#....#....#.....#.....#."},
    {')', ".#.....#.....#....#....#...#...#..."}, {'/', ".........#...#...#...#...#........."},
    {'_', "..............................#####"}, {'-', "...............#####..............."},
    {'^', "..#...#.#.#...#...................."}, {'%', "##..###..#...#...#...#...#..###..##"},
    {',', "....................##....#...#...."}, {':', ".....##...##.........##...##......."},
};

class Canvas {
public:
    Canvas(int width, int height) : width_(width), height_(height), pixels_(3 * size_t(width) * size_t(height), 255) {}

    void fill(int x0, int y0, int x1, int y1, const Rgb& colour)
    {
        x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, width_), y1 = std::min(y1, height_);
        for (int y = y0; y < y1; ++y)
            for (int x = x0; x < x1; ++x) std::memcpy(&pixels_[3 * (size_t(y) * width_ + x)], colour.data(), 3);
    }

    // Text with its top-left corner at (x, y), each font pixel `scale` pixels.
    void text(int x, int y, const std::string& s, int scale, const Rgb& colour)
    {
        for (char raw : s) {
            const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(raw)));
            for (const Glyph& g : kFont)
                if (g.c == c)
                    for (int row = 0; row < 7; ++row)
                        for (int col = 0; col < 5; ++col)
                            if (g.rows[5 * row + col] == '#')
                                fill(x + col * scale, y + row * scale, x + (col + 1) * scale, y + (row + 1) * scale, colour);
            x += 6 * scale;
        }
    }

    static int text_width(const std::string& s, int scale) { return static_cast<int>(s.size()) * 6 * scale - scale; }

    void write(const std::filesystem::path& path) const
    {
        png_image image;
        std::memset(&image, 0, sizeof image);
        image.version = PNG_IMAGE_VERSION;
        image.width = static_cast<png_uint_32>(width_);
        image.height = static_cast<png_uint_32>(height_);
        image.format = PNG_FORMAT_RGB;
        if (!png_image_write_to_file(&image, path.c_str(), 0, pixels_.data(), 3 * width_, nullptr)) {
            const std::string message = image.message;
            png_image_free(&image);
            throw IoError(path.string(), "cannot write the PNG: " + message);
        }
    }

private:
    int width_, height_;
    std::vector<uint8_t> pixels_;
};

std::string tick_label(double value)
{
    char text[32];
    std::snprintf(text, sizeof text, "%g", value);
    return text;
}

} // namespace

void write_histogram_png(const std::vector<HistogramSeries>& series, const std::filesystem::path& path,
                         const HistogramPngOptions& options)
{
    if (series.empty() || series.front().counts.empty())
        throw InputError("a histogram picture needs at least one series with bins", "pass the quality histograms");
    const size_t bins = series.front().counts.size();
    for (const HistogramSeries& s : series)
        if (s.counts.size() != bins)
            throw InputError("histogram series '" + s.label + "' has " + std::to_string(s.counts.size()) +
                                 " bins, not " + std::to_string(bins),
                             "give every series the same bins");
    if (options.width < 200 || options.width > 8000 || options.height < 200 || options.height > 8000)
        throw InputError("a histogram picture of " + std::to_string(options.width) + " x " +
                             std::to_string(options.height) + " pixels",
                         "choose 200 to 8000 pixels each way");

    const int W = options.width, H = options.height;
    const int left = 100, right = W - 30, top = 70, bottom = H - 80;
    Canvas canvas(W, H);

    int64_t largest = 1;
    for (const HistogramSeries& s : series)
        for (int64_t n : s.counts) largest = std::max(largest, n);
    const int decades = std::max(1, static_cast<int>(std::ceil(std::log10(1.0 + static_cast<double>(largest)))));
    const auto y_of = [&](double count) {
        return bottom - static_cast<int>(std::lround((bottom - top) * std::log10(1.0 + count) / decades));
    };

    // Grid and y ticks at powers of ten.
    for (int k = 0; k <= decades; ++k) {
        const double count = std::pow(10.0, k);
        const int y = y_of(count);
        canvas.fill(left, y, right, y + 1, kGrid);
        canvas.fill(left - 6, y, left, y + 1, kBlack);
        const std::string label = k <= 5 ? tick_label(count) : "1E" + std::to_string(k);
        canvas.text(left - 10 - Canvas::text_width(label, 2), y - 7, label, 2, kBlack);
    }
    canvas.text(10, top - 30, "tets (log scale)", 2, kBlack);

    // Bars: one group per bin, one bar per series.
    const double group = double(right - left) / static_cast<double>(bins);
    const double bar = 0.8 * group / static_cast<double>(series.size());
    for (size_t b = 0; b < bins; ++b)
        for (size_t s = 0; s < series.size(); ++s) {
            const int64_t n = series[s].counts[b];
            if (n <= 0) continue;
            const int x0 = left + static_cast<int>(std::lround(group * b + 0.1 * group + bar * s));
            const int x1 = std::max(x0 + 1, left + static_cast<int>(std::lround(group * b + 0.1 * group + bar * (s + 1))));
            canvas.fill(x0, y_of(static_cast<double>(n)), x1, bottom, kPalette[s % kPalette.size()]);
        }

    // Axes, x ticks at every fifth of the range.
    canvas.fill(left - 1, top, left + 1, bottom + 1, kBlack);
    canvas.fill(left - 1, bottom, right, bottom + 2, kBlack);
    for (int k = 0; k <= 5; ++k) {
        const int x = left + static_cast<int>(std::lround((right - left) * k / 5.0));
        canvas.fill(x, bottom, x + 1, bottom + 7, kBlack);
        const std::string label = tick_label(k / 5.0);
        canvas.text(x - Canvas::text_width(label, 2) / 2, bottom + 12, label, 2, kBlack);
    }
    canvas.text((left + right - Canvas::text_width(options.title, 2)) / 2, H - 36, options.title, 2, kBlack);

    // Legend, top right inside the plot.
    int widest = 0;
    for (const HistogramSeries& s : series) widest = std::max(widest, Canvas::text_width(s.label, 2));
    const int lx = right - widest - 40;
    for (size_t s = 0; s < series.size(); ++s) {
        const int ly = 12 + 20 * static_cast<int>(s);
        canvas.fill(lx, ly, lx + 14, ly + 14, kPalette[s % kPalette.size()]);
        canvas.text(lx + 22, ly, series[s].label, 2, kBlack);
    }
    canvas.write(path);
}

} // namespace scalemesh
