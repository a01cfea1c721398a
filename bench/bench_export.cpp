// Export benchmark: the time to write a volume mesh in each format against
// the time to build it (issue 6's goal: ASCII polyMesh under 10% of the
// meshing time, binary under 3%). The mesh comes from the real pipeline on
// the pretzel phantom at 0.25 mm voxels; its size follows L_max (the first
// argument, mm, default 1.5: about 250k tets; 0.9 gives about 1.1M, 0.55 about
// 3.5M), since the method sets element sizes by the feature size, not the
// voxels. Prints a table and the two goals against the meshing time of the
// same run, and writes both to JSON (second argument).
//
// `bench_export --decompose N [--box B] [--json PATH]` (issue 45): the
// torus phantom with B voxels across its box (default 512; L_min 0.5 and
// L_max 12 voxels, as bench_pipeline) meshed once, then its OpenFOAM case
// written two ways, each timed with the peak resident set while it runs:
// the N processor meshes written directly (`[output] decompose = N`, as
// `scalemesh run --decompose N` writes them: the serial polyMesh and the
// pieces), and the serial polyMesh alone followed by OpenFOAM's
// `decomposePar` (method simple, N = nx ny nz split as evenly as it goes) in
// a child process, whose time and peak (read by /usr/bin/time) are its own. The writes'
// peaks are this process's (its peak reset as each starts), so they include
// the run held in memory, as in `scalemesh run`; what was resident before
// each is given too. Needs decomposePar on PATH, /usr/bin/time and
// WM_PROJECT_DIR (set to /usr/share/openfoam when unset).

#include "core/huge_pages.h"
#include "exporters/polymesh_writer.h"
#include "exporters/volume_writers.h"
#include "phantom/phantom.h"
#include "pipeline/memory_estimate.h"
#include "pipeline/pipeline.h"
#include "pipeline/run_case.h"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

namespace {

using namespace scalemesh;
using Clock = std::chrono::steady_clock;

double seconds(const std::function<void()>& work)
{
    const auto start = Clock::now();
    work();
    return std::chrono::duration<double>(Clock::now() - start).count();
}

double mib(double bytes) { return bytes / (1024.0 * 1024.0); }

// N as nx * ny * nz, the factors as close to each other as they go, the
// largest first (8: 2 2 2; 4: 2 2 1; 6: 3 2 1).
std::array<int, 3> split_three(int n)
{
    std::array<int, 3> best = {n, 1, 1};
    for (int x = 1; x <= n; ++x)
        for (int y = 1; y <= n / x; ++y)
            if (n % (x * y) == 0) {
                std::array<int, 3> f = {x, y, n / (x * y)};
                std::sort(f.rbegin(), f.rend());
                if (f[0] - f[2] < best[0] - best[2]) best = f;
            }
    return best;
}

struct Measured {
    double seconds = 0;
    double peak_bytes = 0;   // the peak resident set while it ran
    double before_bytes = 0; // resident as it started (this process; 0 for a child)
};

// `work` in this process, its peak reset as it starts.
Measured measure_here(const std::function<void()>& work)
{
    Measured m;
    reset_peak_resident_memory();
    if (const auto now = resident_memory()) m.before_bytes = double(now->now_bytes);
    m.seconds = seconds(work);
    if (const auto after = resident_memory()) m.peak_bytes = double(after->peak_bytes);
    return m;
}

// `decomposePar -case DIR` in a child process, its output in DIR/log.decomposePar;
// its time and its own peak. The peak is read by /usr/bin/time, which starts
// decomposePar from its own small process: the resident set a child of this
// process reports (wait4) includes the pages it shared with this process
// between fork and exec, the whole mesh. Throws when it fails.
Measured decompose_par(const std::filesystem::path& dir)
{
    std::fflush(stdout);
    const std::string peak_file = (dir / "peak.decomposePar").string();
    const auto start = Clock::now();
    const pid_t pid = fork();
    if (pid < 0) throw std::runtime_error("fork failed");
    if (pid == 0) {
        const std::string log = (dir / "log.decomposePar").string();
        if (!std::freopen(log.c_str(), "w", stdout) || !std::freopen(log.c_str(), "a", stderr)) _exit(127);
        setenv("WM_PROJECT_DIR", "/usr/share/openfoam", 0);
        execl("/usr/bin/time", "time", "-f", "%M", "-o", peak_file.c_str(), "decomposePar", "-case", dir.c_str(),
              static_cast<char*>(nullptr));
        _exit(127);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    Measured m;
    m.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        throw std::runtime_error("decomposePar failed (status " + std::to_string(status) + "; /usr/bin/time, of the "
                                 "Debian package time, is needed); see " + (dir / "log.decomposePar").string());
    std::ifstream in(peak_file);
    double kib = 0;
    if (!(in >> kib) || !(kib > 0)) throw std::runtime_error("no peak of decomposePar in " + peak_file);
    m.peak_bytes = kib * 1024.0;
    return m;
}

int decompose_benchmark(int processors, int box, const std::string& json_path)
{
    const int threads = 2;
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Vec3 lo, hi;
    make_shape("torus", 1.0)->bounds(lo, hi);
    const double h = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}) / box;
    const std::filesystem::path root = std::filesystem::temp_directory_path() / "scalemesh-bench-decompose";
    std::filesystem::remove_all(root);
    std::ostringstream toml;
    toml.precision(17);
    toml << "[input]\nphantom = \"torus\"\nvoxel_size = " << h << "\n"
         << "[sizing]\nL_min = \"0.5 voxels\"\nL_max = \"12 voxels\"\n"
         << "[output]\nsurface = []\nvolume = []\nopenfoam = true\n[run]\nthreads = " << threads << "\n";
    CaseConfig config = parse_case(toml.str(), root, "benchmark");
    std::printf("torus, %d voxels across (voxel %.5f mm), %d threads: meshing...\n", box, h, threads);
    PipelineRun run;
    const double t_mesh = seconds([&] { run = run_pipeline(config, {.sizing = true, .remesh = true, .volume = true}); });
    const size_t tets = run.volume->mesh.tets.size();
    std::printf("%zu tets in %.1f s\n", tets, t_mesh);

    // The pieces directly, as scalemesh run --decompose N.
    CaseConfig pieces = config;
    pieces.directory = root / "pieces";
    pieces.decompose = processors;
    std::filesystem::create_directories(pieces.directory);
    CaseOutputs pieces_out;
    const Measured direct = measure_here([&] { pieces_out = write_case_outputs(pieces, run, {.histograms = false}); });

    // One serial polyMesh, then decomposePar on it.
    CaseConfig serial = config;
    serial.directory = root / "serial";
    serial.decompose = 1;
    std::filesystem::create_directories(serial.directory);
    const Measured serial_write = measure_here([&] { (void)write_case_outputs(serial, run, {.histograms = false}); });
    const std::array<int, 3> n = split_three(processors);
    std::ofstream(serial.directory / "system" / "decomposeParDict")
        << "FoamFile\n{\n    version     2.0;\n    format      ascii;\n    class       dictionary;\n"
           "    object      decomposeParDict;\n}\n\nnumberOfSubdomains " << processors
        << ";\n\nmethod          simple;\n\nsimpleCoeffs\n{\n    n               (" << n[0] << " " << n[1] << " "
        << n[2] << ");\n    delta           0.001;\n}\n";
    const Measured decompose = decompose_par(serial.directory);
    std::filesystem::remove_all(root);

    struct Row {
        std::string way;
        Measured m;
    };
    const Measured both = {serial_write.seconds + decompose.seconds, std::max(serial_write.peak_bytes, decompose.peak_bytes),
                           serial_write.before_bytes};
    const std::string simple = "decomposePar, method simple (" + std::to_string(n[0]) + " " + std::to_string(n[1]) +
                               " " + std::to_string(n[2]) + ")";
    const std::vector<Row> rows = {{"pieces written directly (decompose = " + std::to_string(processors) + ")", direct},
                                   {"serial polyMesh written", serial_write},
                                   {simple + ", its own process", decompose},
                                   {"serial polyMesh, then decomposePar", both}};
    std::printf("\n%zu tets, %d processor meshes; processor faces written directly: %lld\n\n", tets, processors,
                static_cast<long long>(pieces_out.decomposition ? pieces_out.decomposition->processor_faces : 0));
    std::printf("| way | time s | peak RSS MiB | resident before MiB |\n|---|---|---|---|\n");
    for (const Row& r : rows)
        std::printf("| %s | %.2f | %.0f | %s |\n", r.way.c_str(), r.m.seconds, mib(r.m.peak_bytes),
                    r.m.before_bytes > 0 ? std::to_string(std::lround(mib(r.m.before_bytes))).c_str() : "-");
    std::printf("\nwriting the pieces directly: %.2fx the time of the serial polyMesh and decomposePar\n",
                direct.seconds / both.seconds);

    std::ofstream json(json_path);
    json << "{\n  \"box\": " << box << ",\n  \"threads\": " << threads << ",\n  \"tets\": " << tets
         << ",\n  \"processors\": " << processors << ",\n  \"meshing_seconds\": " << t_mesh << ",\n  \"ways\": [\n";
    for (size_t i = 0; i < rows.size(); ++i)
        json << "    {\"way\": \"" << rows[i].way << "\", \"seconds\": " << rows[i].m.seconds
             << ", \"peak_bytes\": " << rows[i].m.peak_bytes << ", \"resident_before_bytes\": " << rows[i].m.before_bytes
             << "}" << (i + 1 < rows.size() ? "," : "") << "\n";
    json << "  ]\n}\n";
    std::printf("wrote %s\n", json_path.c_str());
    return 0;
}

} // namespace

int main(int argc, char** argv)
{
    scalemesh::restart_with_huge_pages(argv);
    if (argc > 1 && std::string(argv[1]) == "--decompose") {
        int processors = 8, box = 512;
        std::string json_path = "bench-decompose.json";
        for (int i = 1; i + 1 < argc; i += 2) {
            const std::string flag = argv[i];
            if (flag == "--decompose") processors = std::stoi(argv[i + 1]);
            else if (flag == "--box") box = std::stoi(argv[i + 1]);
            else if (flag == "--json") json_path = argv[i + 1];
            else {
                std::fprintf(stderr, "unknown option %s: bench_export --decompose N [--box B] [--json PATH]\n", argv[i]);
                return 2;
            }
        }
        return decompose_benchmark(processors, box, json_path);
    }
    const double h = 0.25, L_max = argc > 1 ? std::stod(argv[1]) : 1.5;
    const std::string json_path = argc > 2 ? argv[2] : "bench-export.json";
    CaseConfig config = parse_case("[input]\nphantom = \"pretzel\"\nvoxel_size = " + std::to_string(h) +
                                       "\n[sizing]\nL_min = \"0.5 voxels\"\nL_max = " + std::to_string(L_max) + "\n",
                                   ".", "benchmark");
    const int threads = tbb::this_task_arena::max_concurrency();
    PipelineRun run;
    const double t_all = seconds([&] { run = run_pipeline(config, {.sizing = true, .remesh = true, .volume = true}); });
    double t_mesh = 0;
    for (const StageTime& s : run.stages) t_mesh += s.seconds;
    const TetMesh mesh = export_mesh(run, config.K, config.M);
    std::printf("pretzel, L_max %.2f mm: %zu tets, %zu points; meshing %.2f s (all stages), %.2f s with set-up\n", L_max,
                mesh.tets.size(), mesh.points.size(), t_mesh, t_all);

    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "scalemesh-bench-export";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    struct Row {
        std::string format;
        double seconds;
    };
    std::vector<Row> rows;
    // In `scalemesh run` the writers check the mesh with the face adjacency
    // the volume stage built (inside the meshing time above); alone, a
    // writer builds it first. Both are timed, and the adjacency on its own.
    const TetFaceAdjacency* adjacency = &run.volume->adjacency;
    rows.push_back({"face adjacency alone", seconds([&] { (void)tet_face_adjacency(mesh); })});
    rows.push_back({"polyMesh ascii", seconds([&] { write_polymesh(mesh, dir / "ascii", {.binary = false, .scale = 1e-3, .patch_types = {}, .adjacency = adjacency}); })});
    rows.push_back({"polyMesh binary", seconds([&] { write_polymesh(mesh, dir / "binary", {.binary = true, .scale = 1e-3, .patch_types = {}, .adjacency = adjacency}); })});
    rows.push_back({"polyMesh ascii, own adjacency", seconds([&] { write_polymesh(mesh, dir / "ascii2", {.binary = false, .scale = 1e-3, .patch_types = {}}); })});
    rows.push_back({"polyMesh binary, own adjacency", seconds([&] { write_polymesh(mesh, dir / "binary2", {.binary = true, .scale = 1e-3, .patch_types = {}}); })});
    rows.push_back({"msh 4.1 ascii", seconds([&] { write_volume_msh(mesh, dir / "a41.msh", {.adjacency = adjacency}); })});
    rows.push_back({"msh 4.1 binary", seconds([&] { write_volume_msh(mesh, dir / "b41.msh", {.msh_version = 4.1, .binary = true, .adjacency = adjacency}); })});
    rows.push_back({"msh 2.2 ascii", seconds([&] { write_volume_msh(mesh, dir / "a22.msh", {.msh_version = 2.2, .adjacency = adjacency}); })});
    rows.push_back({"vtk ascii, own adjacency", seconds([&] { write_volume_vtk(mesh, dir / "mesh.vtk"); })});
    std::filesystem::remove_all(dir);

    std::printf("\n%-32s %10s %18s\n", "format", "seconds", "share of meshing");
    for (const Row& r : rows) std::printf("%-32s %10.3f %17.1f%%\n", r.format.c_str(), r.seconds, 100 * r.seconds / t_mesh);

    // The goals, on the writes as `scalemesh run` makes them (with the volume
    // stage's adjacency), against the meshing time of this same run.
    struct Goal {
        const char* name;
        double seconds, limit;
    };
    const Goal goals[] = {{"polymesh_binary", rows[2].seconds, 0.03}, {"polymesh_ascii", rows[1].seconds, 0.10}};
    std::printf("\n%d threads, meshing %.2f s\n", threads, t_mesh);
    for (const Goal& g : goals)
        std::printf("%-16s %8.3f s  %6.2f%% of meshing  (goal under %.0f%%: %s)\n", g.name, g.seconds, 100 * g.seconds / t_mesh,
                    100 * g.limit, g.seconds < g.limit * t_mesh ? "met" : "NOT met");

    std::ofstream json(json_path);
    json << "{\n  \"L_max_mm\": " << L_max << ",\n  \"threads\": " << threads << ",\n  \"tets\": " << mesh.tets.size()
         << ",\n  \"points\": " << mesh.points.size() << ",\n  \"meshing_seconds\": " << t_mesh << ",\n  \"goals\": {\n";
    for (size_t i = 0; i < std::size(goals); ++i)
        json << "    \"" << goals[i].name << "\": {\"seconds\": " << goals[i].seconds
             << ", \"share_of_meshing\": " << goals[i].seconds / t_mesh << ", \"goal_share\": " << goals[i].limit
             << ", \"met\": " << (goals[i].seconds < goals[i].limit * t_mesh ? "true" : "false") << "}"
             << (i + 1 < std::size(goals) ? "," : "") << "\n";
    json << "  },\n  \"writes\": [\n";
    for (size_t i = 0; i < rows.size(); ++i)
        json << "    {\"format\": \"" << rows[i].format << "\", \"seconds\": " << rows[i].seconds
             << ", \"share_of_meshing\": " << rows[i].seconds / t_mesh << "}" << (i + 1 < rows.size() ? "," : "") << "\n";
    json << "  ]\n}\n";
    std::printf("wrote %s\n", json_path.c_str());
    return 0;
}
