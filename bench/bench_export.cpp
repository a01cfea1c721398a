// Export benchmark: the time to write a volume mesh in each format against
// the time to build it (issue 6's goal: ASCII polyMesh under 10% of the
// meshing time, binary under 3%). The mesh comes from the real pipeline on
// the pretzel phantom at 0.25 mm voxels; its size follows L_max (the first
// argument, mm, default 1.5: about 250k tets; 0.9 gives about 1.1M, 0.55 about
// 3.5M), since the method sets element sizes by the feature size, not the
// voxels. Prints a table and the two goals against the meshing time of the
// same run, and writes both to JSON (second argument).

#include "core/huge_pages.h"
#include "exporters/polymesh_writer.h"
#include "exporters/volume_writers.h"
#include "pipeline/pipeline.h"

#include <tbb/task_arena.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>

namespace {

using namespace scalemesh;
using Clock = std::chrono::steady_clock;

double seconds(const std::function<void()>& work)
{
    const auto start = Clock::now();
    work();
    return std::chrono::duration<double>(Clock::now() - start).count();
}

} // namespace

int main(int argc, char** argv)
{
    scalemesh::restart_with_huge_pages(argv);
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
