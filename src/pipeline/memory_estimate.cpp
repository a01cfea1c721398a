#include "pipeline/memory_estimate.h"

#include "core/errors.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <sys/resource.h>
#include <unistd.h>

namespace scalemesh {

namespace {

// Algorithm 4's points of one node (offset_points.cpp, uniform layers).
double node_points(double d, double D, double M, double L_max)
{
    if (!std::isfinite(D)) D = L_max; // an inward ray that escaped: sizing used L_max
    if (!(d > 0) || !(D > 0)) return 1;
    const double layers = std::floor(M / 2);
    const double reach = D / 2;
    if (layers * d / M > reach) return 1 + std::floor(reach * M / d);
    return 1 + layers + std::floor((reach - layers * d / M) / (std::min(D, L_max) / M));
}

} // namespace

int64_t physical_memory()
{
    return static_cast<int64_t>(::sysconf(_SC_PHYS_PAGES)) * static_cast<int64_t>(::sysconf(_SC_PAGE_SIZE));
}

int64_t peak_resident_memory()
{
    rusage usage{};
    ::getrusage(RUSAGE_SELF, &usage);
    return static_cast<int64_t>(usage.ru_maxrss) * 1024; // Linux reports kB
}

std::optional<ResidentMemory> resident_memory()
{
    std::ifstream in("/proc/self/status");
    std::optional<int64_t> peak, now;
    for (std::string line; std::getline(in, line);) {
        const auto kib = [&](const char* key) -> std::optional<int64_t> {
            if (line.rfind(key, 0) != 0) return std::nullopt;
            int64_t value = 0;
            const char* first = line.c_str() + std::strlen(key);
            while (*first == ' ' || *first == '\t') ++first;
            if (std::from_chars(first, line.c_str() + line.size(), value).ec != std::errc()) return std::nullopt;
            return value * 1024;
        };
        if (const auto v = kib("VmHWM:")) peak = v;
        if (const auto v = kib("VmRSS:")) now = v;
    }
    if (!peak || !now) return std::nullopt;
    return ResidentMemory{*peak, *now};
}

bool reset_peak_resident_memory()
{
    std::ofstream out("/proc/self/clear_refs");
    out << "5";
    out.flush();
    return bool(out);
}

int64_t parse_memory_size(const std::string& text, const std::string& what)
{
    const auto refuse = [&] {
        return InputError(what + " '" + text + "' is not a memory size",
                          "give bytes with an optional unit K, M, G or T (powers of 1024), e.g. 8G or 512M");
    };
    // std::from_chars reads the number as written in C, whatever the
    // host's LC_NUMERIC (std::stod would take "1,5" in a German locale and
    // stop at "1.5"'s point).
    // Leading white space and one '+' are skipped, as std::stod skipped them.
    size_t used = 0;
    while (used < text.size() && std::isspace(static_cast<unsigned char>(text[used]))) ++used;
    if (used < text.size() && text[used] == '+') ++used;
    double value = 0;
    const auto [end, error] = std::from_chars(text.data() + used, text.data() + text.size(), value);
    if (error != std::errc()) throw refuse();
    used = static_cast<size_t>(end - text.data());
    std::string unit;
    for (size_t i = used; i < text.size(); ++i)
        if (!std::isspace(static_cast<unsigned char>(text[i]))) unit += static_cast<char>(std::toupper(text[i]));
    if (unit.size() > 1 && (unit.ends_with("IB") || unit.ends_with("B"))) unit = unit.substr(0, 1);
    const std::string units = "BKMGT";
    const size_t power = unit.empty() ? 0 : units.find(unit);
    if (unit.size() > 1 || power == std::string::npos || !(value > 0) || !std::isfinite(value)) throw refuse();
    const double bytes = value * std::pow(1024.0, static_cast<double>(power));
    if (bytes >= 9e18) throw refuse();
    // A bound below a mebibyte is a unit forgotten ("0.5" meaning 0.5G), not
    // a limit any run could keep (0 bytes would mean no limit at all).
    if (bytes < 0x1p20)
        throw InputError(what + " '" + text + "' is " + std::to_string(static_cast<int64_t>(bytes)) +
                             " bytes, less than any run needs",
                         "a bare number is bytes: give a unit, e.g. 8G or 512M");
    return static_cast<int64_t>(bytes);
}

double volume_points(const FeatureSize& sizing, double M, double L_max)
{
    double points = 0;
    for (size_t i = 0; i < sizing.d.size(); ++i) points += node_points(sizing.d[i], sizing.D[i], M, L_max);
    return points;
}

double remeshed_volume_points(const SurfaceMesh& surface, const FeatureSize& sizing, double K, double M,
                              double L_max, const MemoryModel& model)
{
    double points = 0;
    for (const Triangle& t : surface.triangles) {
        const Vec3& a = surface.points[t[0]];
        const double area = 0.5 * norm(cross(surface.points[t[1]] - a, surface.points[t[2]] - a));
        double d = 0, D = 0;
        for (int32_t v : t) d += sizing.d[v] / 3, D += sizing.D[v] / 3;
        const double h = model.remeshed_edge_fraction * K / M * d;
        if (!(h > 0)) continue;
        points += area / (std::sqrt(3.0) / 2 * h * h) * node_points(d, D, M, L_max);
    }
    return points;
}

double estimate_peak_memory(int64_t surface_triangles, double points, const MemoryModel& model)
{
    return model.base + model.per_surface_triangle * static_cast<double>(surface_triangles) +
           model.per_volume_point * points;
}

void require_memory(double estimate, int64_t bound, const std::string& basis)
{
    if (estimate <= static_cast<double>(bound)) return;
    throw InputError("the mesh would need about " + memory_text(estimate) + " of memory (" + basis +
                         "), more than the " + memory_text(static_cast<double>(bound)) + " allowed",
                     "use a larger voxel size, a larger [sizing] L_max or L_min (coarser cells where the "
                     "cross-sections are wide or narrow), a smaller M, or a region of interest (crop the image), or "
                     "raise --max-memory on a machine with more memory");
}

} // namespace scalemesh
