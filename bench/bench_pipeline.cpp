// The whole pipeline against image size (issue 9): one phantom shape at
// voxel sizes that put 64, 128, 256 (and, when asked, 512) voxels across
// its box, each run end to end through `run_case` (phantom, marching cubes,
// smoothing, sizing, remeshing, volume mesh, a binary mesh.msh written) on 1
// and 2 threads. Per size and thread count: the median of N runs of each
// stage and of the whole, peak memory, surface and volume counts, tets per
// second and bytes of peak memory per tet. Beside them, in the same run and
// on the same input, the references of bench/references.h, with ratios.
//
// Element sizes follow the feature size, not the voxels, so L_max is given
// in voxel widths: the mesh then grows with the image as a finer scan of the
// same vessel would make it grow, and the default 12 voxels gives about a
// million tets at 256 voxels across the torus.
//
// Each run of the pipeline is a forked child of a process that holds no mesh
// and has started no threads, so the child's peak resident set (getrusage
// before its references run) is that run's own. The thread counts take turns
// run by run (1, 2, 1, 2, ...), so that a machine whose speed drifts (other
// work on the host) slows both alike and the speed-ups stay fair; the
// references run in the last round. CGAL Mesh_3 runs
// in a child of its own with criteria scaled until its tet count is within
// 20% of ours.
//
// Each run also records every stage's own peak resident set and what it
// left resident ("memory_stages": run_case resets the child's peak as each
// stage starts and as it ends, so the writing of the outputs has its own),
// printed per box as a markdown table "memory per stage".
//
// Writes the figures as JSON, a plot of stage time against output tets
// (gnuplot, when installed) and, with --doc, the markdown tables of
// docs/performance.md followed by the notes file given with --notes; with
// --memory-doc, the memory per stage section alone (the tables, the whole
// run's peak fitted as a + b tets and what 24 and 128 GiB hold by it).

#include "core/huge_pages.h"
#include "pipeline/memory_estimate.h"
#include "pipeline/run_case.h"
#include "phantom/phantom.h"
#include "references.h"
#include "snappy_reference.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace {

using namespace scalemesh;
using namespace scalemesh::bench;
using json = nlohmann::json;
namespace fs = std::filesystem;

// The stages in pipeline order as run_case reports them, and the writing of
// the outputs that follows them ("write": the whole run's time less theirs).
const std::vector<std::string> kStages = {"import", "isosurface", "smoothing", "sizing", "remeshing", "volume", "write"};
// The volume stage's own timers (VolumeResult): layer points (Algorithm 4
// and the filter), insertion (Algorithm 5), removal (the surface's
// triangulation, inside and outside, output, quads put back), flips,
// sliver removal, quality statistics, checks before writing.
const std::vector<std::string> kVolumeParts = {"points", "insertion", "removal", "flips", "slivers", "quality", "checks"};
// Issue 5's volume goal names its parts: insertion + removal + improvement.
double insertion_to_improvement(const json& run);

struct Settings {
    std::string shape = "torus";
    std::vector<int> boxes = {64, 128, 256};
    std::vector<int> threads = {1, 2};
    int repeats = 3;
    double L_max_voxels = 12;
    // The wall layers' construction ([volume] layers). The tables of
    // docs/performance.md are of the paper's Delaunay layers, whose volume
    // stage is compared with plain CGAL insertion of the same points.
    std::string layers = "delaunay";
    double max_memory_gib = 12;   // a size whose predicted peak is above this is skipped
    bool mesh_3 = true;
    int mesh_3_max_box = 256;     // Mesh_3 only up to this size: it takes minutes per million tets
    bool snappy = true;
    int snappy_max_box = 256;     // snappyHexMesh (one run, serial) only up to this size
    std::string json_path = "bench-pipeline.json";
    std::string plot_path = "bench-pipeline.png";
    std::string doc_path;         // empty: no markdown
    std::string notes_path;       // appended to the markdown verbatim
    std::string memory_doc_path;  // empty: none; else the memory per stage section alone (markdown)
    std::vector<std::string> from_json; // non-empty: no measuring, the tables and plot from these result files
    std::string command;          // how this run was started, for the doc
};

std::string number(double value, int digits = 3)
{
    char text[64];
    std::snprintf(text, sizeof text, "%.*g", digits, value);
    return text;
}

std::string fixed(double value, int decimals)
{
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", decimals, value);
    return text;
}

std::string load_average()
{
    std::ifstream in("/proc/loadavg");
    std::string one, five, fifteen;
    in >> one >> five >> fifteen;
    return one + " " + five + " " + fifteen;
}

// Runs `work` in a forked child and returns what it returned, with
// "child_peak_bytes" (the child's whole life) added; {"error": ...} when the
// child failed. The caller must not have started any threads.
json in_child(const std::function<json()>& work)
{
    int channel[2];
    if (pipe(channel) != 0) return {{"error", "pipe failed"}};
    std::fflush(stdout);
    const pid_t pid = fork();
    if (pid < 0) return {{"error", "fork failed"}};
    if (pid == 0) {
        close(channel[0]);
        std::string text;
        try {
            text = work().dump();
        } catch (const std::exception& e) {
            text = json{{"error", e.what()}}.dump();
        }
        for (size_t done = 0; done < text.size();) {
            const ssize_t n = write(channel[1], text.data() + done, text.size() - done);
            if (n <= 0) break;
            done += static_cast<size_t>(n);
        }
        close(channel[1]);
        std::fflush(stdout);
        _exit(0);
    }
    close(channel[1]);
    std::string text;
    char buffer[1 << 16];
    for (ssize_t n; (n = read(channel[0], buffer, sizeof buffer)) > 0;) text.append(buffer, static_cast<size_t>(n));
    close(channel[0]);
    int status = 0;
    rusage usage{};
    wait4(pid, &status, 0, &usage);
    if (text.empty())
        return {{"error", WIFSIGNALED(status) ? "child killed by signal " + std::to_string(WTERMSIG(status))
                                              : "child exited with status " + std::to_string(WEXITSTATUS(status))}};
    json result = json::parse(text);
    result["child_peak_bytes"] = static_cast<double>(usage.ru_maxrss) * 1024.0;
    return result;
}

double own_peak_bytes()
{
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return static_cast<double>(usage.ru_maxrss) * 1024.0;
}

double voxel_size(const Settings& s, int box)
{
    Vec3 lo, hi;
    make_shape(s.shape, 1.0)->bounds(lo, hi);
    return std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}) / box;
}

std::string case_text(const Settings& s, double h, int threads)
{
    std::ostringstream toml;
    toml.precision(17);
    toml << "[input]\nphantom = \"" << s.shape << "\"\nvoxel_size = " << h << "\n"
         << "[sizing]\nL_min = \"0.5 voxels\"\nL_max = \"" << s.L_max_voxels << " voxels\"\n"
         << "[volume]\nlayers = \"" << s.layers << "\"\nmin_dihedral_deg = 10\n"
         << "[output]\nsurface = []\nvolume = [\"mesh.msh\"]\nopenfoam = false\nmsh_binary = true\n"
         << "[run]\nthreads = " << threads << "\n";
    return toml.str();
}

// snappyHexMesh with addLayers on the smoothed surface our sizing and
// remeshing start from, once: background cells of the size that puts as many
// cells in the enclosed volume as we made tets, floor(M/2) layers as our
// mesh has per wall, locationInMesh at the middle of the longest inward ray
// of our sizing (inside by construction).
json measure_snappy(const CaseResult& ours, int layers, const fs::path& dir)
{
    const SurfaceMesh& surface = ours.run.surface;
    const FeatureSize& sizing = *ours.run.sizing;
    size_t deepest = 0;
    for (size_t i = 0; i < surface.points.size(); ++i)
        if (sizing.inward_ok[i] && std::isfinite(sizing.D[i]) && sizing.D[i] > sizing.D[deepest]) deepest = i;
    SnappyParams params;
    params.layers = layers;
    params.inside = surface.points[deepest] - 0.5 * sizing.D[deepest] * sizing.normals[deepest];
    const double tets = static_cast<double>(ours.run.volume->mesh.tets.size());
    params.cell_size = std::cbrt(std::abs(signed_volume(surface)) / tets);
    std::printf("  snappyHexMesh, cells of %.4f mm, %d layers...\n", params.cell_size, layers);
    const SnappyRun r = snappy_hex_mesh(surface, params, dir);
    if (!r.error.empty()) return {{"error", r.error}};
    fs::remove_all(dir); // the case (meshes of up to a million cells) is not kept
    return {{"seconds", r.seconds},
            {"snappy_seconds", r.snappy_seconds},
            {"cells", r.cells},
            {"cell_size_mm", params.cell_size},
            {"layers_asked", layers},
            {"mean_layers", r.mean_layers},
            {"thickness_percent", r.thickness_percent}};
}

// Our pipeline once end to end, then (with `references`) volumeToMesh on
// the same grid and (with `cgal` too) the CGAL references on the run's
// surfaces and points.
json measure_pipeline(const Settings& s, int box, int threads, bool references, bool cgal, const fs::path& work_dir)
{
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
    const double h = voxel_size(s, box);
    const fs::path dir = work_dir / ("box" + std::to_string(box) + "-t" + std::to_string(threads));
    fs::create_directories(dir);
    std::ofstream(dir / "scalemesh.toml") << case_text(s, h, threads);

    std::map<std::string, std::vector<double>> samples;
    CaseResult last;
    std::optional<ResidentMemory> written; // the peak while writing the outputs, and what is resident after
    int retries = 0;
    {
        const auto start = Clock::now();
        // run_case's memory bound: the machine's memory (0), or
        // --max-memory-gib where that is more (its estimate is conservative
        // at the largest boxes, as scalemesh --max-memory).
        const double asked = s.max_memory_gib * (1 << 30);
        const double machine = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
        // run_case resets the process's peak as each stage starts and reads
        // it as the stage ends (memory.stages); reset again as a stage ends,
        // the peak after the last one is the writing of the outputs alone.
        const auto peak_per_stage = [](const StageTime& t) {
            if (t.seconds >= 0) reset_peak_resident_memory();
        };
        last = run_case(dir, peak_per_stage, std::nullopt, asked > machine ? static_cast<int64_t>(asked) : 0);
        const double total = seconds_since(start);
        written = resident_memory();
        std::map<std::string, double> stage;
        for (const StageTime& t : last.run.stages) {
            const std::string name = t.name.substr(0, t.name.find(" (retry")); // retries count to their stage
            stage[name] += t.seconds;
            retries += t.name != name;
        }
        double staged = 0;
        for (const auto& [name, seconds] : stage) staged += seconds;
        stage["write"] = total - staged;
        for (const std::string& name : kStages) samples[name].push_back(stage[name]);
        samples["total"].push_back(total);
        const VolumeResult& v = *last.run.volume;
        const double parts[] = {v.seconds_points, v.seconds_insertion, v.seconds_classify, v.seconds_flips,
                                v.seconds_slivers, v.seconds_quality, v.seconds_checks};
        for (size_t k = 0; k < kVolumeParts.size(); ++k) samples["volume " + kVolumeParts[k]].push_back(parts[k]);
    }
    json out;
    out["box"] = box;
    out["threads"] = threads;
    out["voxel_size_mm"] = h;
    // Per stage (the names of kStages; a retry counts to its stage): its own
    // peak and what it left resident, bytes. The run's peak is the largest.
    json stage_memory = json::array();
    double peak = own_peak_bytes();
    const auto add_stage_memory = [&](const std::string& name, double peak_bytes, double held_bytes) {
        peak = std::max(peak, peak_bytes);
        for (json& entry : stage_memory)
            if (entry["stage"] == name) {
                entry["peak_bytes"] = std::max(entry["peak_bytes"].get<double>(), peak_bytes);
                entry["held_after_bytes"] = held_bytes;
                return;
            }
        stage_memory.push_back({{"stage", name}, {"peak_bytes", peak_bytes}, {"held_after_bytes", held_bytes}});
    };
    for (const StageMemory& m : last.run.stage_memory)
        add_stage_memory(m.stage.substr(0, m.stage.find(" (retry")), double(m.peak_bytes), double(m.resident_after_bytes));
    if (written && !stage_memory.empty()) add_stage_memory("write", double(written->peak_bytes), double(written->now_bytes));
    out["peak_bytes"] = peak;
    out["memory_stages"] = stage_memory;
    out["inside_voxels"] = last.run.inside_voxels;
    out["isosurface_triangles"] = last.run.isosurface.triangles;
    out["smoothed_vertices"] = last.run.facts.vertices;
    out["remeshed_triangles"] = last.run.remeshed->surface.triangles.size();
    out["tets"] = last.run.volume->mesh.tets.size();
    out["points"] = last.run.volume->mesh.points.size();
    out["volume_retries"] = retries;
    {
        const VolumeResult& v = *last.run.volume;
        const QualityReport& q = v.after_slivers;
        out["quality"] = {{"min_aspect_ratio", q.min_aspect_ratio},
                          {"fraction_below_0_1", q.fraction_below_0_1},
                          {"below_0_02", q.below_0_02},
                          {"min_dihedral_deg", q.min_dihedral_deg},
                          {"max_non_orthogonality_deg", v.max_non_orthogonality_deg},
                          {"layer_coverage", v.layers.coverage()},
                          {"released_layer_points", v.released_layer_points}};
        out["warnings"] = last.warnings; // the floors the run missed
    }
    for (const auto& [name, values] : samples) {
        out["seconds"][name] = median(values);
        out["samples"][name] = values;
    }

    if (!references) return out;
    const auto shape = make_shape(s.shape, h);
    const auto grid = voxelize(*shape, {.voxel_size = h});
    size_t vdb_triangles = 0;
    out["ref_volume_to_mesh"]["seconds"] = median_of_reported(s.repeats, [&] {
        const ReferenceRun r = openvdb_volume_to_mesh(*grid, 0.5);
        vdb_triangles = r.items;
        return r.seconds;
    });
    out["ref_volume_to_mesh"]["items"] = vdb_triangles;
    if (!cgal) return out;

    // isotropic_remeshing at one length, the median of our target K/M d,
    // for as many iterations as our remeshing has cycles.
    const CaseConfig config = read_case(dir);
    std::vector<double> target = last.run.sizing->d;
    for (double& t : target) t *= config.K / config.M;
    const double length = median(target);
    size_t cgal_triangles = 0;
    out["ref_isotropic_remeshing"]["seconds"] = median_of_reported(s.repeats, [&] {
        const ReferenceRun r = cgal_isotropic_remeshing(last.run.surface, length, config.remesh_cycles);
        cgal_triangles = r.items;
        return r.seconds;
    });
    out["ref_isotropic_remeshing"]["items"] = cgal_triangles;
    out["ref_isotropic_remeshing"]["target_edge_mm"] = length;
    size_t cells = 0;
    out["ref_delaunay"]["seconds"] = median_of_reported(s.repeats, [&] {
        const ReferenceRun r = cgal_delaunay(last.run.volume->mesh.points);
        cells = r.items;
        return r.seconds;
    });
    out["ref_delaunay"]["items"] = cells;

    // Layers our mesh realised: per surface node, the consecutive
    // layermaking points inserted, over the floor(M/2) asked.
    const int layers = static_cast<int>(std::floor(config.M / 2));
    double realised = 0;
    for (const int32_t r : last.run.volume->layers.realised) realised += r;
    out["layers_asked"] = layers;
    out["mean_realised_layers"] = realised / std::max<size_t>(1, last.run.volume->layers.realised.size());
    if (s.snappy && box <= s.snappy_max_box) out["ref_snappy"] = measure_snappy(last, layers, dir / "snappy");
    return out;
}

// CGAL Mesh_3 on the same label image with cell and facet size f L_max
// (facet distance one voxel); f starts at `factor` and is scaled by the cube
// root of the tet ratio until the count is within 20% of `tets`. Only the
// runs at the final f count.
json measure_mesh_3(const Settings& s, int box, double tets, double factor)
{
    const double h = voxel_size(s, box);
    const double L_max = s.L_max_voxels * h;
    const auto shape = make_shape(s.shape, h);
    const auto grid = voxelize(*shape, {.voxel_size = h});
    std::vector<double> times;
    ReferenceRun r;
    for (int attempt = 0; attempt < 4; ++attempt) {
        const Mesh3Criteria criteria{.cell_size = factor * L_max, .facet_size = factor * L_max, .facet_distance = h};
        r = cgal_mesh_3(*grid, criteria);
        const double ratio = static_cast<double>(r.items) / tets;
        if (std::abs(ratio - 1) <= 0.2) break;
        factor *= std::cbrt(ratio);
    }
    times.push_back(r.seconds);
    const Mesh3Criteria criteria{.cell_size = factor * L_max, .facet_size = factor * L_max, .facet_distance = h};
    while (static_cast<int>(times.size()) < s.repeats) times.push_back(cgal_mesh_3(*grid, criteria).seconds);
    return {{"seconds", median(times)},
            {"samples", times},
            {"tets", r.items},
            {"size_factor", factor},
            {"cell_size_mm", factor * L_max},
            {"peak_bytes", own_peak_bytes()}};
}

// --- Output -----------------------------------------------------------------

double seconds_of(const json& run, const std::string& stage) { return run["seconds"][stage].get<double>(); }

const json* find_run(const json& sizes, int box, int threads)
{
    for (const json& size : sizes)
        if (size["box"] == box)
            for (const json& run : size["runs"])
                if (run["threads"] == threads && !run.contains("error")) return &run;
    return nullptr;
}

double insertion_to_improvement(const json& run)
{
    double sum = 0;
    for (const char* part : {"volume insertion", "volume removal", "volume flips", "volume slivers"})
        sum += seconds_of(run, part);
    return sum;
}

// Whether the run has the volume split (result files written before it
// was recorded do not).
bool has_volume_parts(const json& run) { return run["seconds"].contains("volume insertion"); }

// Meshing without the reading of the image and the writing of the mesh: what
// Mesh_3's time is compared with.
double meshing_seconds(const json& run)
{
    return seconds_of(run, "isosurface") + seconds_of(run, "smoothing") + seconds_of(run, "sizing") +
           seconds_of(run, "remeshing") + seconds_of(run, "volume");
}

void write_plot(const Settings& s, const json& sizes)
{
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
        std::printf("gnuplot not found: no plot (bash setup.sh bench installs it)\n");
        return;
    }
    // The data and the gnuplot script are scratch files; only the PNG stays.
    const fs::path scratch = fs::temp_directory_path() / ("scalemesh-bench-plot-" + std::to_string(getpid()));
    fs::create_directories(scratch);
    const fs::path data = scratch / "times.dat";
    std::ofstream out(data);
    std::vector<std::string> columns = kStages;
    columns.push_back("total");
    int blocks = 0;
    for (int threads : s.threads) {
        out << "# threads " << threads << ": tets";
        for (const std::string& c : columns) out << " " << c;
        out << "\n";
        for (const json& size : sizes)
            if (const json* run = find_run(sizes, size["box"], threads)) {
                out << (*run)["tets"].get<double>();
                for (const std::string& c : columns) out << " " << seconds_of(*run, c);
                out << "\n";
            }
        out << "\n\n";
        ++blocks;
    }
    out.close();
    std::ostringstream script;
    script << "set terminal pngcairo size 1000,700 font ',11'\nset output '" << s.plot_path << "'\n"
           << "set logscale xy\nset grid\nset key outside right\n"
           << "set xlabel 'output tets'\nset ylabel 'seconds (median of " << s.repeats << ")'\n"
           << "set title '" << s.shape << " phantom, boxes of " << s.boxes.front() << " to " << s.boxes.back()
           << " voxels across: time per stage against output size'\nplot ";
    for (int b = 0; b < blocks; ++b)
        for (size_t c = 0; c < columns.size(); ++c)
            script << (b || c ? ", " : "") << "'" << data.string() << "' index " << b << " using 1:" << c + 2
                   << " with linespoints lc " << c + 1 << " dt " << b + 1 << " pt " << 7 - b * 2 << " title '"
                   << columns[c] << ", " << s.threads[b] << " thread" << (s.threads[b] == 1 ? "" : "s") << "'";
    script << "\n";
    const fs::path script_path = scratch / "plot.gp";
    std::ofstream(script_path) << script.str();
    if (std::system(("gnuplot '" + script_path.string() + "'").c_str()) == 0)
        std::printf("wrote %s\n", s.plot_path.c_str());
    fs::remove_all(scratch);
}

std::string join(const std::vector<int>& values)
{
    std::string text;
    for (size_t i = 0; i < values.size(); ++i)
        text += (i == 0 ? "" : i + 1 == values.size() ? " and " : ", ") + std::to_string(values[i]);
    return text;
}

// The box as the tables show it, with its number of runs when it differs
// from the rest.
std::string box_label(const Settings& s, const json& size)
{
    std::string label = size["box_text"];
    if (size.contains("repeats") && size["repeats"] != s.repeats)
        label += " (" + std::to_string(size["repeats"].get<int>()) + " run" + (size["repeats"] == 1 ? ")" : "s)");
    return label;
}

// The floors a run's mesh missed, as one line ("" when it met them all): a
// face beyond OpenFOAM's 70 degrees, then the run's own floor warnings.
std::string missed_floors(const json& run)
{
    const bool beyond = run["quality"]["max_non_orthogonality_deg"].get<double>() >= 70;
    std::string missed = beyond ? "a face beyond 70 degrees" : "";
    for (const json& w : run["warnings"]) missed += (missed.empty() ? "" : "; ") + w.get<std::string>();
    return missed;
}

std::string mib(double bytes) { return fixed(bytes / (1024.0 * 1024.0), 0); }

std::string ratio(double ours, double reference) { return reference > 0 ? fixed(ours / reference, 2) : "-"; }

// One box's memory per stage (a run of measure_pipeline): each stage's own
// peak and what it left resident, in MiB and in bytes per tet of the final
// mesh; "" when the run has no stage figures.
std::string stage_memory_table(const json& size, const json& run)
{
    if (run.contains("error") || !run.contains("memory_stages") || run["memory_stages"].empty()) return "";
    const double tets = run["tets"];
    std::ostringstream md;
    md << "Memory per stage, " << size["box_text"].get<std::string>() << ", " << run["threads"] << " thread"
       << (run["threads"] == 1 ? "" : "s") << ", " << number(tets / 1e6, 4) << "M tets:\n\n"
       << "| stage | peak MiB | peak B/tet | held after MiB | held B/tet |\n|---|---|---|---|---|\n";
    for (const json& m : run["memory_stages"]) {
        const double peak = m["peak_bytes"], held = m["held_after_bytes"];
        md << "| " << m["stage"].get<std::string>() << " | " << mib(peak) << " | " << fixed(peak / tets, 0) << " | "
           << mib(held) << " | " << fixed(held / tets, 0) << " |\n";
    }
    return md.str();
}

// The memory per stage of every box at the largest thread count, then the
// whole run's peak fitted as bytes = a + b tets (least squares over those
// boxes), its error at each, and the largest mesh and box 24 and 128 GiB
// would hold by it (tets growing as the cube of the box, from the largest
// box measured).
std::string memory_markdown(const Settings& s, const json& sizes, bool with_commands = false)
{
    struct Point {
        std::string box;
        int voxels;
        double tets, peak;
    };
    std::vector<Point> points;
    std::ostringstream md;
    md << "## Memory per stage\n\n"
       << "Each stage's own peak resident set (the process's peak reset as the stage starts, "
       << "`/proc/self/clear_refs`, read from `/proc/self/status` as it ends; report.json's `memory.stages`) and "
       << "what it left resident, per tet of the final mesh; `write` is the outputs (`mesh.msh`, report.json, "
       << "quality.png), its held figure with the whole run still in memory. " << s.threads.back() << " thread"
       << (s.threads.back() == 1 ? "" : "s") << ".\n\n";
    if (with_commands) md << "Measured and written with:\n\n```sh\n" << s.command << "\n```\n\n";
    for (const json& size : sizes) {
        const json* run = find_run(sizes, size["box"], s.threads.back());
        if (!run) continue;
        const std::string table = stage_memory_table(size, *run);
        if (table.empty()) continue;
        md << table << "\n";
        points.push_back({size["box_text"], size["box"], (*run)["tets"], (*run)["peak_bytes"]});
    }
    if (points.size() < 2) return points.empty() ? "" : md.str();
    double mean_t = 0, mean_p = 0;
    for (const Point& p : points) mean_t += p.tets / double(points.size()), mean_p += p.peak / double(points.size());
    double stt = 0, stp = 0;
    for (const Point& p : points) stt += (p.tets - mean_t) * (p.tets - mean_t), stp += (p.tets - mean_t) * (p.peak - mean_p);
    const double b = stp / stt, a = mean_p - b * mean_t;
    md << "The whole run's peak against the tets, fitted by least squares over these boxes: **bytes = "
       << fixed(a / (1024.0 * 1024.0), 0) << " MiB + " << fixed(b, 1) << " B x tets**.\n\n"
       << "| box | tets | measured peak MiB | model MiB | model error |\n|---|---|---|---|---|\n";
    for (const Point& p : points) {
        const double model = a + b * p.tets;
        md << "| " << p.box << " | " << number(p.tets / 1e6, 4) << "M | " << mib(p.peak) << " | " << mib(model) << " | "
           << (model >= p.peak ? "+" : "") << fixed(100 * (model - p.peak) / p.peak, 1) << "% |\n";
    }
    const Point& largest = *std::max_element(points.begin(), points.end(),
                                             [](const Point& x, const Point& y) { return x.tets < y.tets; });
    md << "\n| memory | largest box measured within it | tets by the model | box by the model |\n|---|---|---|---|\n";
    for (const double gib : {24.0, 128.0}) {
        const double bytes = gib * (1 << 30), tets = (bytes - a) / b;
        std::string measured = "-";
        for (const Point& p : points)
            if (p.peak <= bytes) measured = p.box + " (" + mib(p.peak) + " MiB)";
        md << "| " << number(gib) << " GiB | " << measured << " | " << number(tets / 1e6, 3) << "M | about "
           << fixed(largest.voxels * std::cbrt(tets / largest.tets), 0) << " voxels across |\n";
    }
    md << "\n";
    return md.str();
}

// The markdown of docs/performance.md: how the figures were made, the tables,
// the goals, then the notes file.
std::string markdown(const Settings& s, const json& result)
{
    const json& sizes = result["sizes"];
    std::ostringstream md;
    md << "# Performance\n\n"
       << "<!-- Generated by bench/bench_pipeline; edit bench/performance-notes.md or the harness, not this file. -->\n\n"
       << "Figures from `bench/bench_pipeline` (issue 9): the " << s.shape
       << " phantom voxelised so that its box is " << join(s.boxes)
       << " voxels across its longest side, each run end to end "
       << "through `run_case` (phantom, marching cubes, smoothing, sizing, remeshing, volume mesh, a binary "
       << "`mesh.msh` plus `report.json` and `quality.png` written) with L_min = 0.5 voxels and L_max = "
       << number(s.L_max_voxels) << " voxels, so the mesh grows with the image. Every time is the median of "
       << s.repeats << " runs (fewer where the box says so); references run in the same process on the same "
       << "input.\n\n"
       << "**These figures come from a shared machine**: " << result["machine"]["cores"]
       << " cores that other engineers' builds and tests were using at the same time (load average "
       << result["machine"]["load_before"].get<std::string>() << " before the run, "
       << result["machine"]["load_after"].get<std::string>() << " after; 1, 5 and 15 minutes). Absolute "
       << "times are therefore pessimistic and noisy; the ratios against references measured in the same run "
       << "are the steadier figures.\n\n"
       << "Reproduce (Release build; `bash setup.sh bench` runs this and the other benchmarks):\n\n```sh\n"
       << "cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DSCALEMESH_BENCH=ON\n"
       << "cmake --build build --target bench_pipeline\n" << s.command << "\n```\n\n"
       << "Every sample and the reference counts are in the result file the run writes, `" << s.json_path
       << "` (not kept in the repository).\n\n";

    md << "## Our pipeline\n\n"
       << "Box: voxels along x, y, z. Triangles: marching cubes output; vertices: the smoothed surface that "
       << "sizing runs on. Stage columns in seconds; *write* is the whole run less its stages (export and "
       << "files). Peak: the resident set of the forked child that ran only these repeats.\n\n"
       << "| box | threads | triangles | vertices | tets | import | isosurface | smoothing | sizing | remeshing | "
          "volume | write | end to end | tets/s | peak MiB | bytes/tet |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const json& size : sizes)
        for (const json& run : size["runs"]) {
            if (run.contains("error")) {
                md << "| " << box_label(s, size) << " | " << run["threads"] << " | failed: "
                   << run["error"].get<std::string>() << " |||||||||||||\n";
                continue;
            }
            const double tets = run["tets"].get<double>();
            md << "| " << box_label(s, size) << " | " << run["threads"] << " | "
               << run["isosurface_triangles"] << " | " << run["smoothed_vertices"] << " | " << run["tets"];
            for (const std::string& stage : kStages) md << " | " << fixed(seconds_of(run, stage), 2);
            md << " | **" << fixed(seconds_of(run, "total"), 2) << "** | " << number(tets / seconds_of(run, "total"))
               << " | " << mib(run["peak_bytes"].get<double>()) << " | " << fixed(run["peak_bytes"].get<double>() / tets, 0)
               << " |\n";
        }
    for (const json& size : result["skipped"])
        md << "\nNot run: " << size["box_text"].get<std::string>() << ", " << size["reason"].get<std::string>() << ".\n";

    md << "\n" << memory_markdown(s, sizes);
    md << "## Mesh quality\n\n"
       << "The last run's mesh of each box, against the floors every run checks (`floor_warnings`: no tet below "
       << "aspect ratio 0.1, 99% of the wall nodes with D >= L_min keeping all their layers, and here "
       << "`min_dihedral_deg = 10`) and OpenFOAM's non-orthogonality bound of 70 degrees (measured on the "
       << "mesh as `checkMesh` measures it, cut, not rounded, to the digits shown). *Released*: layer points "
       << "let off their layers where a cell still missed 10 degrees or 70.\n\n"
       << "| box | threads | tets | worst aspect ratio | below 0.1 | below 0.02 | smallest dihedral (deg) | "
          "largest non-orthogonality (deg) | layer coverage | released | floors |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const json& size : sizes)
        for (const json& run : size["runs"]) {
            if (run.contains("error") || !run.contains("quality")) continue;
            const json& q = run["quality"];
            const std::string floors = missed_floors(run);
            md << "| " << box_label(s, size) << " | " << run["threads"] << " | " << run["tets"] << " | "
               << fixed(q["min_aspect_ratio"].get<double>(), 4) << " | "
               << fixed(100 * q["fraction_below_0_1"].get<double>(), 4) << "% | " << q["below_0_02"] << " | "
               << fixed(q["min_dihedral_deg"].get<double>(), 2) << " | "
               << fixed(std::floor(1000 * q["max_non_orthogonality_deg"].get<double>()) / 1000, 3) << " | "
               << fixed(100 * q["layer_coverage"].get<double>(), 2) << "% | " << q["released_layer_points"] << " | "
               << (floors.empty() ? "met" : "**missed**: " + floors) << " |\n";
        }

    md << "\n## Against the references\n\n"
       << "Ratio = ours / reference on the same input (above 1: we are slower). Isosurface: OpenVDB "
       << "`volumeToMesh` on the same label grid, on the same thread count. Remeshing: CGAL "
       << "`isotropic_remeshing` of the same smoothed surface at one length (the median of our K/M d), as many "
       << "iterations as our cycles; ours includes the sizing of its result. Volume: CGAL "
       << "`Delaunay_triangulation_3` built from our output points. Whole pipeline: CGAL Mesh_3 `make_mesh_3` "
       << "on the same label image (facet distance one voxel, cell and facet size scaled until its tet count "
       << "is within 20% of ours), against our meshing stages (isosurface to volume; neither reads nor writes). "
       << "The CGAL references are sequential, so their 1-thread times serve both rows.\n\n"
       << "| box | threads | isosurface s | volumeToMesh s | ratio | remeshing s | isotropic_remeshing s | ratio | "
          "volume s | Delaunay s | ratio | meshing s | Mesh_3 s (tets) | ratio | Mesh_3 peak bytes/tet |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const json& size : sizes) {
        for (const json& run : size["runs"]) {
            if (run.contains("error")) continue;
            const json* cgal = run.contains("ref_delaunay") ? &run : find_run(sizes, size["box"], s.threads.front());
            const json& vdb = run["ref_volume_to_mesh"];
            md << "| " << box_label(s, size) << " | " << run["threads"] << " | "
               << fixed(seconds_of(run, "isosurface"), 3) << " | " << fixed(vdb["seconds"].get<double>(), 3) << " | "
               << ratio(seconds_of(run, "isosurface"), vdb["seconds"]) << " | ";
            if (cgal && cgal->contains("ref_isotropic_remeshing")) {
                const double remesh = (*cgal)["ref_isotropic_remeshing"]["seconds"], dt = (*cgal)["ref_delaunay"]["seconds"];
                md << fixed(seconds_of(run, "remeshing"), 2) << " | " << fixed(remesh, 2) << " | "
                   << ratio(seconds_of(run, "remeshing"), remesh) << " | " << fixed(seconds_of(run, "volume"), 2)
                   << " | " << fixed(dt, 2) << " | " << ratio(seconds_of(run, "volume"), dt) << " | ";
            } else {
                md << "- | - | - | - | - | - | ";
            }
            md << fixed(meshing_seconds(run), 2) << " | ";
            if (size.contains("mesh_3") && !size["mesh_3"].contains("error")) {
                const json& m3 = size["mesh_3"];
                md << fixed(m3["seconds"].get<double>(), 2) << " (" << m3["tets"] << ") | "
                   << ratio(meshing_seconds(run), m3["seconds"]) << " | "
                   << fixed(m3["peak_bytes"].get<double>() / m3["tets"].get<double>(), 0) << " |\n";
            } else {
                md << "- | - | - |\n";
            }
        }
    }

    md << "\n## The volume stage against plain CGAL insertion\n\n"
       << "The volume stage's own timers (medians): layer points (Algorithm 4 and the interior-point filter), "
       << "insertion (Algorithm 5, layer by layer in slabs), removal (the surface points' triangulation, inside "
       << "and outside, the output of the inside, surface quads put back), flips, sliver removal, quality "
       << "statistics (three histograms) and the checks before writing (renumbering, face adjacency, "
       << "conformity, topology). Issue 5's goal names insertion + removal + improvement; the whole stage "
       << "is the *volume* column above. CGAL: `Delaunay_triangulation_3` of the same final points, "
       << "sequential.\n\n"
       << "| box | threads | points | insertion | removal | flips | slivers | quality | checks | whole | CGAL | "
          "ratio whole | insertion + removal + improvement | ratio |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const json& size : sizes)
        for (const json& run : size["runs"]) {
            if (run.contains("error") || !has_volume_parts(run)) continue;
            const json* cgal = run.contains("ref_delaunay") ? &run : find_run(sizes, size["box"], s.threads.front());
            if (!cgal || !cgal->contains("ref_delaunay")) continue;
            const double dt = (*cgal)["ref_delaunay"]["seconds"];
            md << "| " << box_label(s, size) << " | " << run["threads"] << " |";
            for (const std::string& part : kVolumeParts) md << " " << fixed(seconds_of(run, "volume " + part), 2) << " |";
            md << " " << fixed(seconds_of(run, "volume"), 2) << " | " << fixed(dt, 2) << " | "
               << ratio(seconds_of(run, "volume"), dt) << " | " << fixed(insertion_to_improvement(run), 2) << " | "
               << ratio(insertion_to_improvement(run), dt) << " |\n";
        }

    md << "\n## Against snappyHexMesh\n\n"
       << "OpenFOAM's `blockMesh` and `snappyHexMesh` (v1912, serial) with `addLayers` on the smoothed surface "
       << "written as STL, run once per size in the same process as our 1-thread runs (`bench/snappy_reference.cpp`): "
       << "background hex cells of the size that puts as many cells in the enclosed volume as we made tets, no "
       << "refinement, floor(M/2) layers asked on the surface (relative sizes, final layer 0.3 of the cell), "
       << "`locationInMesh` at the middle of our longest inward ray. Its cell count, the average layers on the "
       << "surface patch and the layers' thickness as a percentage of the asked come from its log. Ours: the "
       << "meshing stages (isosurface to volume) on 1 thread, and per surface node the consecutive layermaking "
       << "points our mesh realised, averaged.\n\n"
       << "| box | our meshing s | tets | our layers (mean / asked) | snappyHexMesh s | cells | ratio | "
          "snappyHexMesh layers (mean / asked) | its layer thickness % |\n"
       << "|---|---|---|---|---|---|---|---|---|\n";
    for (const json& size : sizes) {
        const json* run = find_run(sizes, size["box"], s.threads.front());
        if (!run || !run->contains("ref_snappy")) continue;
        const json& snappy = (*run)["ref_snappy"];
        md << "| " << box_label(s, size) << " | " << fixed(meshing_seconds(*run), 2) << " | " << (*run)["tets"] << " | "
           << fixed((*run)["mean_realised_layers"].get<double>(), 2) << " / " << (*run)["layers_asked"] << " | ";
        if (snappy.contains("error")) {
            md << "failed: " << snappy["error"].get<std::string>() << " |||||\n";
            continue;
        }
        md << fixed(snappy["seconds"].get<double>(), 2) << " | " << snappy["cells"] << " | "
           << ratio(meshing_seconds(*run), snappy["seconds"]) << " | " << fixed(snappy["mean_layers"].get<double>(), 2)
           << " / " << snappy["layers_asked"] << " | " << fixed(snappy["thickness_percent"].get<double>(), 1) << " |\n";
    }

    md << "\n## Thread speed-up\n\n"
       << "Median time on " << s.threads.front() << " thread over median time on " << s.threads.back()
       << " threads, per stage (`tbb::global_control` and `[run] threads` limit every stage).\n\n| box |";
    for (const std::string& stage : kStages) md << " " << stage << " |";
    md << " end to end |\n|---|";
    for (size_t i = 0; i <= kStages.size(); ++i) md << "---|";
    md << "\n";
    for (const json& size : sizes) {
        const json* one = find_run(sizes, size["box"], s.threads.front());
        const json* two = find_run(sizes, size["box"], s.threads.back());
        if (!one || !two || s.threads.size() < 2) continue;
        md << "| " << box_label(s, size) << " |";
        for (const std::string& stage : kStages) md << " " << ratio(seconds_of(*one, stage), seconds_of(*two, stage)) << " |";
        md << " " << ratio(seconds_of(*one, "total"), seconds_of(*two, "total")) << " |\n";
    }

    md << "\n## Goals\n\n"
       << "Issue 9's goals, on the largest thread count. Margin: measured over goal (below 1 is met; for the "
       << "speed-up, goal over measured).\n\n| goal | box | measured | goal | margin | met |\n|---|---|---|---|---|---|\n";
    for (const json& g : result["goals"])
        md << "| " << g["goal"].get<std::string>() << " | " << g["box"].get<std::string>() << " | "
           << g["measured"].get<std::string>() << " | " << g["target"].get<std::string>() << " | "
           << fixed(g["margin"].get<double>(), 2) << " | " << (g["met"].get<bool>() ? "yes" : "**no**") << " |\n";

    md << "\n![Time per stage against output tets](" << fs::path(s.plot_path).filename().string() << ")\n\n";
    if (!s.notes_path.empty()) {
        std::ifstream notes(s.notes_path);
        md << notes.rdbuf();
    }
    return md.str();
}

// The goals of issue 9 from the measured sizes: each a row with the margin
// measured / goal (goal / measured for the speed-up).
json goals(const Settings& s, const json& sizes)
{
    json rows = json::array();
    const int threads = s.threads.back();
    const auto add = [&](const std::string& goal, const json& size, const std::string& measured,
                         const std::string& target, double margin) {
        rows.push_back({{"goal", goal},
                        {"box", size["box_text"]},
                        {"measured", measured},
                        {"target", target},
                        {"margin", margin},
                        {"met", margin <= 1.0}});
    };
    for (const json& size : sizes) {
        const json* run = find_run(sizes, size["box"], threads);
        if (!run) continue;
        const double tets = (*run)["tets"];
        if (size["box"] == 256)
            add("256^3 phantom to a written mesh of about 1M tets", size,
                fixed(seconds_of(*run, "total"), 1) + " s, " + number(tets / 1e6, 3) + "M tets", "15 s",
                seconds_of(*run, "total") / 15.0);
    }
    for (const json& size : sizes) {
        const json* run = find_run(sizes, size["box"], threads);
        const json* cgal = run && run->contains("ref_delaunay") ? run : find_run(sizes, size["box"], s.threads.front());
        if (!run || !cgal || !cgal->contains("ref_delaunay")) continue;
        const double r = seconds_of(*run, "volume") / (*cgal)["ref_delaunay"]["seconds"].get<double>();
        add("volume stage / plain CGAL insertion", size, fixed(r, 2) + "x", "2x", r / 2.0);
        if (has_volume_parts(*run)) {
            const double core = insertion_to_improvement(*run) / (*cgal)["ref_delaunay"]["seconds"].get<double>();
            add("insertion + removal + improvement / plain CGAL insertion", size, fixed(core, 2) + "x", "2x",
                core / 2.0);
        }
    }
    for (const json& size : sizes) {
        const json* run = find_run(sizes, size["box"], threads);
        if (!run) continue;
        const double per_million = seconds_of(*run, "sizing") / ((*run)["smoothed_vertices"].get<double>() / 1e6);
        add("sizing per million surface vertices", size, fixed(per_million, 2) + " s", "1 s", per_million);
    }
    for (const json& size : sizes) {
        const json* run = find_run(sizes, size["box"], threads);
        if (!run) continue;
        const double bytes = (*run)["peak_bytes"].get<double>() / (*run)["tets"].get<double>();
        add("peak memory per output tet", size, fixed(bytes, 0) + " B", "600 B", bytes / 600.0);
    }
    // Issue 30: the volume stage's time per tet from the 256 box up, the
    // slowest over the fastest; and every box's mesh meeting its floors.
    {
        const json *fastest = nullptr, *slowest = nullptr;
        double low = 0, high = 0;
        for (const json& size : sizes) {
            const json* run = find_run(sizes, size["box"], threads);
            if (!run || size["box"].get<int>() < 256) continue;
            const double per_tet = seconds_of(*run, "volume") / (*run)["tets"].get<double>();
            if (!fastest || per_tet < low) fastest = &size, low = per_tet;
            if (!slowest || per_tet > high) slowest = &size, high = per_tet;
        }
        if (fastest && fastest != slowest)
            add("volume stage time per tet from 256 up, slowest (" + (*slowest)["box_text"].get<std::string>() +
                    ") over fastest",
                *fastest, fixed(high / low, 2) + "x (" + fixed(1e6 * high, 1) + " / " + fixed(1e6 * low, 1) + " us)",
                "1.5x", high / low / 1.5);
    }
    for (const json& size : sizes) {
        const json* run = find_run(sizes, size["box"], threads);
        if (!run || !run->contains("quality")) continue;
        const bool met = missed_floors(*run).empty();
        add("mesh meets the quality floors (Mesh quality above)", size, met ? "all met" : "missed", "all met",
            met ? 0.0 : 2.0);
    }
    // The speed-up at the largest size run on both thread counts.
    const json* largest = nullptr;
    for (const json& size : sizes)
        if (s.threads.size() >= 2 && find_run(sizes, size["box"], s.threads.front()) &&
            find_run(sizes, size["box"], s.threads.back()))
            largest = &size;
    if (largest) {
        const json& one = *find_run(sizes, (*largest)["box"], s.threads.front());
        const json& two = *find_run(sizes, (*largest)["box"], s.threads.back());
        for (const std::string stage : {"isosurface", "smoothing", "sizing", "volume"}) {
            const double speedup = seconds_of(one, stage) / seconds_of(two, stage);
            add(std::to_string(s.threads.back()) + "-thread speed-up, " + stage, *largest, fixed(speedup, 2) + "x",
                "1.5x", 1.5 / speedup);
        }
    }
    return rows;
}

std::vector<int> int_list(const std::string& text)
{
    std::vector<int> values;
    std::stringstream in(text);
    for (std::string item; std::getline(in, item, ',');) values.push_back(std::stoi(item));
    return values;
}

} // namespace

int main(int argc, char** argv)
{
    scalemesh::restart_with_huge_pages(argv);
    Settings s;
    std::string boxes = "64,128,256", threads = "1,2";
    CLI::App app{"The whole pipeline against image size, with references and ratios (issue 9)."};
    app.add_option("--shape", s.shape, "phantom shape")->capture_default_str();
    app.add_option("--boxes", boxes, "voxels across the phantom's box, comma separated")->capture_default_str();
    app.add_option("--threads", threads, "thread counts, comma separated, fewest first")->capture_default_str();
    app.add_option("--repeats", s.repeats, "runs per figure; the median is reported")->capture_default_str()->check(CLI::PositiveNumber);
    app.add_option("--L-max-voxels", s.L_max_voxels, "L_max in voxel widths")->capture_default_str();
    app.add_option("--layers", s.layers, "the wall layers' construction, as [volume] layers")
        ->check(CLI::IsMember({"delaunay", "prisms"}))
        ->capture_default_str();
    app.add_option("--max-memory-gib", s.max_memory_gib,
                   "skip a size whose predicted peak is above this; above the machine's memory, also the runs' own "
                   "bound (scalemesh --max-memory)")
        ->capture_default_str();
    app.add_flag("!--no-mesh-3", s.mesh_3, "skip the CGAL Mesh_3 reference");
    app.add_option("--mesh-3-max-box", s.mesh_3_max_box, "largest box to run Mesh_3 on")->capture_default_str();
    app.add_flag("!--no-snappy", s.snappy, "skip the snappyHexMesh reference");
    app.add_option("--snappy-max-box", s.snappy_max_box, "largest box to run snappyHexMesh on")->capture_default_str();
    app.add_option("--json", s.json_path, "result file")->capture_default_str();
    app.add_option("--plot", s.plot_path, "PNG of time against output tets")->capture_default_str();
    app.add_option("--doc", s.doc_path, "markdown tables to write (docs/performance.md)");
    app.add_option("--notes", s.notes_path, "markdown appended to --doc");
    app.add_option("--memory-doc", s.memory_doc_path,
                   "the memory per stage section of --doc alone, with the fitted model, to write (markdown)");
    app.add_option("--from-json", s.from_json,
                   "write --doc and --plot from earlier result files, measuring nothing; the sizes of later files "
                   "are added to the first's (a large size measured with fewer repeats)");
    CLI11_PARSE(app, argc, argv);
    s.boxes = int_list(boxes);
    s.threads = int_list(threads);
    s.command = "build/bench/bench_pipeline";
    for (int i = 1; i < argc; ++i) s.command += std::string(" ") + argv[i];

    if (!s.from_json.empty()) {
        const std::string merge_command = s.command;
        json result = json::parse(std::ifstream(s.from_json.front()));
        s.command = result["command"];
        s.shape = result["shape"];
        s.L_max_voxels = result["L_max_voxels"];
        s.layers = result.value("layers", std::string("delaunay")); // files from before the option: Delaunay
        s.repeats = result["repeats"];
        s.boxes = result["boxes"].get<std::vector<int>>();
        s.threads = result["threads"].get<std::vector<int>>();
        s.json_path = s.from_json.front();
        for (size_t i = 1; i < s.from_json.size(); ++i) {
            const json more = json::parse(std::ifstream(s.from_json[i]));
            s.command += "\n" + more["command"].get<std::string>();
            s.json_path += "`, `" + s.from_json[i];
            for (json size : more["sizes"]) {
                size["repeats"] = more["repeats"];
                s.boxes.push_back(size["box"]);
                result["sizes"].push_back(size);
            }
        }
        s.command += "\n" + merge_command;
        result["goals"] = goals(s, result["sizes"]);
        write_plot(s, result["sizes"]);
        if (!s.doc_path.empty()) std::ofstream(s.doc_path) << markdown(s, result);
        if (!s.memory_doc_path.empty()) std::ofstream(s.memory_doc_path) << memory_markdown(s, result["sizes"], true);
        return 0;
    }

    const fs::path work_dir = fs::temp_directory_path() / ("scalemesh-bench-pipeline-" + std::to_string(getpid()));
    json result;
    result["command"] = s.command;
    result["boxes"] = s.boxes;
    result["threads"] = s.threads;
    result["shape"] = s.shape;
    result["L_max_voxels"] = s.L_max_voxels;
    result["layers"] = s.layers;
    result["repeats"] = s.repeats;
    result["machine"] = {{"cores", sysconf(_SC_NPROCESSORS_ONLN)}, {"load_before", load_average()}};
    result["sizes"] = json::array();
    result["skipped"] = json::array();
    double bytes_per_voxel = 0; // peak over box voxels at the last size, for the prediction
    double mesh_3_factor = 0.7;

    for (int box : s.boxes) {
        const double h = voxel_size(s, box);
        Vec3 lo, hi;
        make_shape(s.shape, h)->bounds(lo, hi);
        const int nx = int(std::ceil((hi.x - lo.x) / h)), ny = int(std::ceil((hi.y - lo.y) / h)),
                  nz = int(std::ceil((hi.z - lo.z) / h));
        const std::string box_text = std::to_string(nx) + "x" + std::to_string(ny) + "x" + std::to_string(nz);
        const double predicted = bytes_per_voxel * nx * ny * nz;
        if (predicted > s.max_memory_gib * (1 << 30)) {
            const std::string reason = "predicted peak " + fixed(predicted / (1 << 30), 1) + " GiB (from the previous size) "
                                       "is above the " + number(s.max_memory_gib) + " GiB allowed (--max-memory-gib)";
            std::printf("%s: skipped, %s\n", box_text.c_str(), reason.c_str());
            result["skipped"].push_back({{"box", box}, {"box_text", box_text}, {"reason", reason}});
            continue;
        }
        json size = {{"box", box}, {"box_text", box_text}, {"voxel_size_mm", h}, {"runs", json::array()}};
        std::map<int, std::vector<json>> parts; // per thread count, one per run
        std::printf("%s: %d runs of the pipeline on each of", box_text.c_str(), s.repeats);
        for (int t : s.threads) std::printf(" %d", t);
        std::printf(" threads, taking turns...\n");
        for (int r = 0; r < s.repeats; ++r)
            for (int t : s.threads) {
                const bool last_round = r + 1 == s.repeats, cgal = t == s.threads.front();
                parts[t].push_back(
                    in_child([&] { return measure_pipeline(s, box, t, last_round, last_round && cgal, work_dir); }));
            }
        for (int t : s.threads) {
            // The last run carries the references; the samples, peaks and
            // retries of all runs are merged into it.
            json run = parts[t].back();
            for (const json& part : parts[t])
                if (part.contains("error")) run = part;
            if (!run.contains("error")) {
                run["samples"] = json::object();
                double peak = 0, child_peak = 0;
                int retries = 0;
                for (const json& part : parts[t]) {
                    for (const auto& [name, values] : part["samples"].items())
                        for (const json& v : values) run["samples"][name].push_back(v);
                    peak = std::max(peak, part["peak_bytes"].get<double>());
                    child_peak = std::max(child_peak, part["child_peak_bytes"].get<double>());
                    retries += part["volume_retries"].get<int>();
                }
                for (const auto& [name, values] : run["samples"].items()) {
                    std::vector<double> v = values.get<std::vector<double>>();
                    run["seconds"][name] = median(v);
                }
                run["peak_bytes"] = peak;
                run["child_peak_bytes"] = child_peak;
                run["volume_retries"] = retries / s.repeats;
                std::printf("  %d thread%s: %s tets, end to end %.2f s (import %.2f, isosurface %.2f, smoothing %.2f, "
                            "sizing %.2f, remeshing %.2f, volume %.2f, write %.2f), peak %s MiB\n",
                            t, t == 1 ? "" : "s", number(run["tets"].get<double>(), 4).c_str(), seconds_of(run, "total"),
                            seconds_of(run, "import"), seconds_of(run, "isosurface"), seconds_of(run, "smoothing"),
                            seconds_of(run, "sizing"), seconds_of(run, "remeshing"), seconds_of(run, "volume"),
                            seconds_of(run, "write"), mib(run["peak_bytes"]).c_str());
                bytes_per_voxel = std::max(bytes_per_voxel, run["peak_bytes"].get<double>() / (double(nx) * ny * nz));
            } else {
                std::printf("  %d thread%s: failed: %s\n", t, t == 1 ? "" : "s", run["error"].get<std::string>().c_str());
            }
            size["runs"].push_back(run);
            if (const std::string table = stage_memory_table(size, run); !table.empty())
                std::printf("\n%s\n", table.c_str());
        }
        const json* ours = nullptr;
        for (const json& run : size["runs"])
            if (!run.contains("error")) ours = &run;
        if (s.mesh_3 && box <= s.mesh_3_max_box && ours) {
            std::printf("%s: CGAL Mesh_3 to about %s tets...\n", box_text.c_str(), number((*ours)["tets"].get<double>(), 4).c_str());
            const double tets = (*ours)["tets"];
            size["mesh_3"] = in_child([&] { return measure_mesh_3(s, box, tets, mesh_3_factor); });
            if (!size["mesh_3"].contains("error")) {
                mesh_3_factor = size["mesh_3"]["size_factor"];
                std::printf("  %s tets in %.2f s\n", number(size["mesh_3"]["tets"].get<double>(), 4).c_str(),
                            size["mesh_3"]["seconds"].get<double>());
            }
        }
        result["sizes"].push_back(size);
        std::ofstream(s.json_path) << result.dump(2) << "\n"; // what there is so far, should a later size fail
    }
    fs::remove_all(work_dir);

    result["machine"]["load_after"] = load_average();
    result["goals"] = goals(s, result["sizes"]);
    std::ofstream(s.json_path) << result.dump(2) << "\n";
    std::printf("wrote %s\n", s.json_path.c_str());
    for (const json& g : result["goals"])
        std::printf("goal %-45s %-12s %-22s (goal %s): %s\n", g["goal"].get<std::string>().c_str(),
                    g["box"].get<std::string>().c_str(), g["measured"].get<std::string>().c_str(),
                    g["target"].get<std::string>().c_str(), g["met"].get<bool>() ? "met" : "missed");
    write_plot(s, result["sizes"]);
    if (!s.doc_path.empty()) {
        std::ofstream(s.doc_path) << markdown(s, result);
        std::printf("wrote %s\n", s.doc_path.c_str());
    }
    if (!s.memory_doc_path.empty()) {
        std::ofstream(s.memory_doc_path) << memory_markdown(s, result["sizes"], true);
        std::printf("wrote %s\n", s.memory_doc_path.c_str());
    }
    return 0;
}
