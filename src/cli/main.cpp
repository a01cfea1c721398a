// The scalemesh command line: verbs phantom, surface, run, init, check and
// options. Errors
// from the library become one line on stderr and a non-zero exit code; an
// interrupt removes every output still being written. Progress goes to stderr
// (cli/progress.h).

#include "cli/progress.h"
#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/huge_pages.h"
#include "core/version.h"
#include "exporters/surface_writers.h"
#include "gmsh_io/msh_reader.h"
#include "importers/surface_importer.h"
#include "importers/vdb_importer.h"
#include "phantom/phantom.h"
#include "pipeline/case_init.h"
#include "pipeline/memory_estimate.h"
#include "pipeline/options_table.h"
#include "pipeline/run_case.h"
#include "volume/quality.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <unistd.h>

namespace {

using namespace scalemesh;

void on_signal(int signal)
{
    if (defer_signal_during_commit(signal)) return;
    remove_pending_outputs();
    ::_exit(128 + signal);
}

std::string extension_of(const std::string& path) { return std::filesystem::path(path).extension().string(); }

// OpenFOAM's habit: `scalemesh -case DIR [options]` is `scalemesh run DIR
// [options]`. CLI11 reads "-case" as four short flags, so the arguments are
// rewritten before parsing. Throws CLI::ParseError for a "-case" without a
// directory or beside another verb.
std::vector<std::string> openfoam_style(int argc, char** argv, const CLI::App& app)
{
    std::vector<std::string> args(argv + 1, argv + argc);
    const auto at = std::find(args.begin(), args.end(), "-case");
    if (at == args.end()) return args;
    if (at + 1 == args.end()) throw CLI::ArgumentMismatch("-case needs the case directory: scalemesh -case DIR");
    for (auto a = args.begin(); a != args.end(); ++a)
        for (const CLI::App* verb : app.get_subcommands([](const CLI::App*) { return true; }))
            if (a != at + 1 && *a == verb->get_name())
                throw CLI::ExtrasError("-case DIR is `scalemesh run DIR`: give it without the verb '" + *a + "'",
                                       CLI::ExitCodes::ExtrasError);
    const std::string dir = *(at + 1);
    args.erase(at, at + 2);
    args.insert(args.begin(), {"run", dir});
    return args;
}

// The listener that passes each stage event to both displays.
StageListener both(StageListener a, StageListener b)
{
    return [a = std::move(a), b = std::move(b)](const StageTime& stage) {
        a(stage);
        b(stage);
    };
}

} // namespace

int main(int argc, char** argv)
{
    restart_with_huge_pages(argv);
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    std::signal(SIGHUP, on_signal); // a closed terminal: the run ends as on SIGINT, its outputs removed

    CLI::App app{"scalemesh " SCALEMESH_VERSION
                 ": scale-invariant layered tetrahedral meshes from segmented images, for CFD"};
    app.footer("As in OpenFOAM, scalemesh -case DIR [OPTIONS] is scalemesh run DIR [OPTIONS].");
    app.require_subcommand(1);
    app.fallthrough(); // -q and -v after the verb too
    app.set_version_flag("--version", SCALEMESH_VERSION);
    bool quiet = false, verbose = false;
    app.add_flag("-q,--quiet", quiet, "Print nothing but errors");
    app.add_flag("-v,--verbose", verbose, "Also print each stage as it starts, and per-stage details at the end");

    // phantom
    std::string shape, phantom_out;
    PhantomParams phantom;
    auto* phantom_cmd = app.add_subcommand("phantom", "Write a phantom label image (0/1 voxels) as an OpenVDB grid");
    std::string shapes;
    for (const std::string& n : phantom_names()) shapes += (shapes.empty() ? "" : ", ") + n;
    phantom_cmd->add_option("shape", shape, "One of: " + shapes)->required();
    phantom_cmd->add_option("-o,--output", phantom_out, "Output .vdb file")->required();
    phantom_cmd->add_option("--voxel-size", phantom.voxel_size, "Voxel width in mm (default 0.5)");
    phantom_cmd->add_option("--noise", phantom.noise, "Per-voxel noise amplitude in voxel widths (default 0)");
    phantom_cmd->add_option("--seed", phantom.seed, "Seed of the noise (default 1)");

    // surface
    std::string surface_in, surface_out, grid_name;
    std::optional<double> iso;
    int connectivity = 6;
    std::optional<int> sweeps;
    bool sizing = false;
    std::string L_min, L_max;
    auto* surface_cmd = app.add_subcommand(
        "surface", "Marching cubes surface of an image (optionally smoothed, with the feature size field)");
    surface_cmd->add_option("input", surface_in,
                            "Input image (.vdb, .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd) or closed surface "
                            "(.stl, .ply, .obj, .vtp, .msh)")
        ->required();
    std::string units;
    surface_cmd->add_option("--units", units, "Unit of a surface file's coordinates: mm (default), cm, m or um");
    surface_cmd->add_option("-o,--output", surface_out, "Output surface: .msh, .vtk or .stl")->required();
    surface_cmd->add_option("--grid", grid_name, "VDB grid name (default: the first scalar grid)");
    surface_cmd->add_option("--iso", iso, "Iso value (default 0 for level sets, 0.5 for label grids)");
    surface_cmd->add_option("--connectivity", connectivity, "Inside voxel connectivity, 6 or 26 (default 6)")
        ->check(CLI::IsMember({6, 26}));
    surface_cmd->add_option("--smooth", sweeps,
                            "Volume-conserving smoothing sweeps (default 0, or 10 with --sizing)");
    surface_cmd->add_flag("--sizing", sizing, "Compute D, D_out and d (Algorithm 1) and write them as fields");
    bool remesh = false;
    surface_cmd->add_flag("--remesh", remesh,
                          "Also remesh to edge length K/M d (Algorithm 6) and write d and the edge-length ratio");
    surface_cmd->add_option("--L-min", L_min, "Smallest feature size, e.g. \"0.5 voxels\" or \"1 mm\"");
    surface_cmd->add_option("--L-max", L_max, "Largest feature size (default: the largest extent)");

    // run
    std::string case_dir;
    auto* run_cmd = app.add_subcommand("run", "Run a case directory (scalemesh.toml) and write its outputs into it, "
                                              "with the run's log in log.scalemesh (also: scalemesh -case DIR)");
    run_cmd->add_option("case", case_dir, "Case directory holding scalemesh.toml")->required();
    std::optional<int> threads;
    run_cmd->add_option("--threads", threads,
                        "Worker threads of every parallel stage, overriding [run] threads (0: every core)");
    std::optional<int> decompose;
    run_cmd->add_option("--decompose", decompose,
                        "Also write the OpenFOAM case as N processor meshes (processor0 .. processor<N-1>) for "
                        "mpirun -np N, overriding [output] decompose");
    bool strict = false;
    run_cmd->add_flag("--strict", strict,
                      "Exit with code 6 when the mesh misses one of the case's floors (layer coverage, worst aspect "
                      "ratio, smallest dihedral angle; [volume] in the case file); the outputs are still written");
    std::string max_memory;
    run_cmd->add_option("--max-memory", max_memory,
                        "Memory the run may use, e.g. 8G or 512M (default: the machine's physical memory); a "
                        "case whose estimated peak is larger stops before the heavy stages");

    // init
    std::string init_dir, init_file;
    bool init_force = false;
    auto* init_cmd = app.add_subcommand("init", "Write a first case file for an image or a surface: how its voxels "
                                                "become inside, its openings, its units, the defaults commented");
    init_cmd->add_option("case", init_dir, "Case directory to write scalemesh.toml into (made if missing)")->required();
    init_cmd->add_option("file", init_file,
                         "Image (.vdb, .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd, .vti) or surface (.stl, .ply, .obj, "
                         ".vtp, .msh)")
        ->required();
    init_cmd->add_flag("--force", init_force, "Replace the case directory's scalemesh.toml");

    // check
    std::string check_mesh;
    auto* check_cmd = app.add_subcommand("check", "Quality report of a volume mesh (.msh): validity, aspect ratio, "
                                                  "dihedral angles, histogram");
    check_cmd->add_option("mesh", check_mesh, "Volume mesh (.msh, as scalemesh run writes it)")->required();

    // options
    bool options_json = false;
    auto* options_cmd = app.add_subcommand("options", "List the meshing options: case-file section and key, Python "
                                                      "keyword, kind, default, range or choices, unit, meaning");
    options_cmd->add_flag("--json", options_json, "As a JSON array (read by the Gmsh GUI client, scalemesh_gui.py)");

    try {
        std::vector<std::string> args = openfoam_style(argc, argv, app);
        std::reverse(args.begin(), args.end()); // CLI11 takes them last first
        app.parse(args);
    } catch (const CLI::ParseError& e) {
        // --help and --version end with 0; every other command-line error
        // with 2, the code of any bad input (CLI11's own are 100 and up).
        return app.exit(e) == 0 ? 0 : 2;
    }
    const Verbosity verbosity = quiet ? Verbosity::Quiet : (verbose ? Verbosity::Verbose : Verbosity::Normal);
    const bool terminal = ::isatty(STDERR_FILENO) == 1;
    // Stages of a run: import, isosurface, smoothing, sizing, remeshing, volume.
    ProgressDisplay display(verbosity, stderr, terminal, *run_cmd ? 6 : 4);

    try {
        if (*options_cmd) {
            std::fputs((options_json ? mesh_options_json() : mesh_options_text()).c_str(), stdout);
        } else if (*phantom_cmd) {
            if (extension_of(phantom_out) != ".vdb")
                throw InputError("the phantom output '" + phantom_out + "' must end in .vdb",
                                 "give -o NAME.vdb");
            const auto solid = make_shape(shape, phantom.voxel_size);
            const auto grid = voxelize(*solid, phantom);
            write_vdb(*grid, phantom_out);
            if (verbosity != Verbosity::Quiet)
                std::fprintf(stderr, "scalemesh: wrote %s (%llu inside voxels of %g mm)\n", phantom_out.c_str(),
                             static_cast<unsigned long long>(grid->activeVoxelCount()), phantom.voxel_size);
        } else if (*surface_cmd) {
            const std::string ext = extension_of(surface_out);
            if (ext != ".msh" && ext != ".vtk" && ext != ".stl")
                throw InputError("the output '" + surface_out + "' has an unknown format",
                                 "give a file ending in .msh, .vtk or .stl");
            // The verb is a case without a case file: its flags fill one in.
            std::string text = "[input]\nfile = " + CLI::detail::to_string(std::quoted(surface_in)) + "\n";
            if (!grid_name.empty()) text += "grid = " + CLI::detail::to_string(std::quoted(grid_name)) + "\n";
            if (!units.empty()) text += "units = " + CLI::detail::to_string(std::quoted(units)) + "\n";
            if (iso) text += "iso = " + std::to_string(*iso) + "\n";
            text += "connectivity = " + std::to_string(connectivity) + "\n";
            sizing = sizing || remesh;
            text += "[smoothing]\nsweeps = " + std::to_string(sweeps.value_or(sizing ? 10 : 0)) + "\n";
            text += "[sizing]\n";
            if (!L_min.empty()) text += "L_min = " + CLI::detail::to_string(std::quoted(L_min)) + "\n";
            if (!L_max.empty()) text += "L_max = " + CLI::detail::to_string(std::quoted(L_max)) + "\n";
            const CaseConfig config = parse_case(text, ".", "command line");
            const PipelineRun run =
                run_pipeline(config, {.sizing = sizing, .remesh = remesh, .volume = false}, display.listener());
            write_surface(final_surface(run), surface_fields(run, config.K, config.M), surface_out);
            if (verbosity != Verbosity::Quiet) std::fprintf(stderr, "scalemesh: wrote %s\n", surface_out.c_str());
        } else if (*init_cmd) {
            const std::filesystem::path target = std::filesystem::path(init_dir) / "scalemesh.toml";
            std::error_code ec;
            if (std::filesystem::exists(target, ec) && !init_force)
                throw InputError(target.string() + " exists already",
                                 "give another case directory, or --force to replace it");
            const InitialCase initial = initial_case(init_file, init_dir);
            AtomicOutput out(target, true);
            {
                std::ofstream file(out.temporary());
                file << initial.text;
                if (!file.flush()) throw IoError(target.string(), "cannot write the case file");
            }
            out.commit();
            if (verbosity != Verbosity::Quiet) {
                for (const std::string& note : initial.notes) std::fprintf(stderr, "scalemesh: %s\n", note.c_str());
                std::fprintf(stderr, "scalemesh: wrote %s; run it with: scalemesh run %s\n", target.c_str(),
                             init_dir.c_str());
            }
        } else if (*check_cmd) {
            if (extension_of(check_mesh) != ".msh")
                throw InputError("cannot check '" + check_mesh + "': only Gmsh .msh volume meshes are read",
                                 "give the mesh.msh that scalemesh run writes");
            const TetMesh mesh = read_msh_tet_mesh(check_mesh);
            const TetMeshFacts facts = tet_mesh_facts(mesh);
            const QualityReport q = quality_report(mesh);
            std::printf("%s\n  points %zu, tets %zu, boundary triangles %zu, volume %.9g mm^3\n", check_mesh.c_str(),
                        mesh.points.size(), mesh.tets.size(), mesh.boundary_faces.size(), facts.volume);
            std::printf("  tets with volume <= 0: %lld; faces of three or more tets: %lld; boundary %s\n",
                        static_cast<long long>(facts.nonpositive_tets), static_cast<long long>(facts.overshared_faces),
                        facts.boundary_matches ? "closed and equal to the boundary triangles"
                                               : "NOT equal to the boundary triangles");
            std::printf("  aspect ratio (2 sqrt(6) r_in / l_max): min %.4f, mean %.4f; below 0.1: %.3f%%; below 0.02: %lld\n",
                        q.min_aspect_ratio, q.mean_aspect_ratio, 100 * q.fraction_below_0_1,
                        static_cast<long long>(q.below_0_02));
            std::printf("  smallest dihedral angle %.2f degrees\n  aspect ratio histogram:\n", q.min_dihedral_deg);
            int64_t largest = 1;
            for (int64_t n : q.histogram) largest = std::max(largest, n);
            for (size_t b = 0; b < q.histogram.size(); ++b)
                std::printf("    %.2f-%.2f %9lld %s\n", b / 20.0, (b + 1) / 20.0, static_cast<long long>(q.histogram[b]),
                            std::string(static_cast<size_t>(50 * q.histogram[b] / largest), '#').c_str());
            const bool valid = facts.nonpositive_tets == 0 && facts.overshared_faces == 0 && facts.boundary_matches;
            std::printf("  %s\n", valid ? "valid" : "INVALID");
            return valid ? 0 : 4;
        } else if (*run_cmd) {
            const auto start = std::chrono::steady_clock::now();
            const CaseConfig config = read_case(case_dir);
            const int64_t memory_bound = max_memory.empty() ? 0 : parse_memory_size(max_memory, "--max-memory");
            // log.scalemesh: the lines a run prints when not quiet, as a log
            // file wants them (no bar), put in place with the outputs only
            // when the run succeeds.
            AtomicOutput log_output(config.directory / "log.scalemesh");
            std::unique_ptr<std::FILE, int (*)(std::FILE*)> log_file(std::fopen(log_output.temporary().c_str(), "w"),
                                                                    &std::fclose);
            if (!log_file) throw IoError(log_output.path().string(), "cannot write the run's log");
            std::optional<ProgressDisplay> log_display;
            log_display.emplace(verbosity == Verbosity::Verbose ? Verbosity::Verbose : Verbosity::Normal,
                                log_file.get(), false, 6);
            const CaseResult result =
                run_case(case_dir, both(display.listener(), log_display->listener()), threads, memory_bound, decompose);
            const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            // The warnings about the input (units, face labels) come first,
            // before the summary, since they may change how to read it; the
            // floors the mesh missed after it.
            const size_t about_input = result.input_warnings;
            const auto warn = [&](size_t from, size_t to) {
                for (size_t i = from; i < to; ++i) {
                    const std::string& w = result.warnings[i];
                    if (verbosity != Verbosity::Quiet || strict) std::fprintf(stderr, "scalemesh: warning: %s\n", w.c_str());
                    std::fprintf(log_file.get(), "scalemesh: warning: %s\n", w.c_str());
                }
            };
            warn(0, about_input);
            display.summary(config, result, seconds);
            log_display->summary(config, result, seconds);
            warn(about_input, result.warnings.size());
            const size_t floors = result.warnings.size() - about_input;
            const bool missed_floors = strict && !result.warnings.empty();
            std::string strict_line = "scalemesh: error: ";
            if (floors > 0) strict_line += "the mesh misses " + std::to_string(floors) + " of the case's floors";
            if (floors > 0 && about_input > 0) strict_line += ", and ";
            if (about_input > 0)
                strict_line += "the run warned " + std::to_string(about_input) + " time" + (about_input == 1 ? "" : "s") +
                               " about its input";
            strict_line += " (--strict); the outputs and report.json (\"warnings\") are written for inspection. Hint: ";
            if (about_input > 0) strict_line += "act on the warnings about the input (units, face labels, openings)";
            if (floors > 0 && about_input > 0) strict_line += ", then ";
            if (floors > 0) strict_line += "refine (smaller L_max, larger M) or lower the floors in [volume]";
            strict_line += "\n";
            if (missed_floors) std::fputs(strict_line.c_str(), log_file.get());
            log_display.reset();
            if (std::fclose(log_file.release()) != 0)
                throw IoError(log_output.path().string(), "cannot write the run's log");
            log_output.commit();
            if (missed_floors) {
                std::fputs(strict_line.c_str(), stderr);
                return 6;
            }
        }
    } catch (const scalemesh::Error& e) {
        display.clear();
        std::fprintf(stderr, "scalemesh: error: %s\n", e.what());
        return e.exit_code();
    } catch (const std::bad_alloc&) {
        display.clear();
        std::fprintf(stderr, "scalemesh: error: out of memory. Hint: use a larger voxel size or a smaller region\n");
        return 5;
    } catch (const std::exception& e) {
        display.clear();
        std::fprintf(stderr, "scalemesh: internal error: %s\n", e.what());
        return 70;
    }
    return 0;
}
