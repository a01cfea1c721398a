// Issue 10: reproducible output, provenance in the .msh files, and
// interruption. The same case with --threads 1 gives byte-identical files on
// every run, and the same files with two threads; the .msh files carry the
// version, parameters and input; a run stopped by SIGINT or SIGTERM at any
// moment leaves no temporary file behind and the case's earlier outputs
// either all untouched or all replaced by complete new ones.

#include "cli_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <csignal>
#include <fstream>
#include <map>
#include <spawn.h>
#include <thread>
#include <unistd.h>

extern char** environ;

namespace scalemesh {
namespace {

std::string slurp(const std::filesystem::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Drops what is measured rather than computed: times and peak memory.
void drop_measurements(nlohmann::json& j)
{
    if (j.is_object()) {
        for (auto it = j.begin(); it != j.end();) {
            if (it.key().rfind("seconds", 0) == 0 || it.key() == "measured_peak_bytes" || it.key() == "peak_bytes" ||
                it.key().rfind("resident_after_bytes", 0) == 0) {
                it = j.erase(it);
            } else {
                drop_measurements(it.value());
                ++it;
            }
        }
    } else if (j.is_array()) {
        for (auto& item : j) drop_measurements(item);
    }
}

// Every file under `dir` except the case file and the run's log (stage
// times), by relative path. report.json is kept without its times and
// memory (the run's and each stage's), which differ between runs, and without
// the thread count.
std::map<std::string, std::string> outputs(const std::filesystem::path& dir)
{
    std::map<std::string, std::string> files;
    for (const auto& entry : std::filesystem::recursive_directory_iterator(dir)) {
        if (!entry.is_regular_file() || entry.path().filename() == "scalemesh.toml" ||
            entry.path().filename() == "log.scalemesh")
            continue;
        const std::string name = std::filesystem::relative(entry.path(), dir).string();
        std::string bytes = slurp(entry.path());
        if (name == "report.json") {
            nlohmann::json report = nlohmann::json::parse(bytes);
            drop_measurements(report);
            report["parameters"].erase("threads");
            bytes = report.dump(1);
        }
        files[name] = std::move(bytes);
    }
    return files;
}

std::vector<std::string> differing(const std::map<std::string, std::string>& a, const std::map<std::string, std::string>& b)
{
    std::vector<std::string> names;
    for (const auto& [name, bytes] : a)
        if (!b.count(name) || b.at(name) != bytes) names.push_back(name);
    for (const auto& [name, bytes] : b)
        if (!a.count(name)) names.push_back(name);
    return names;
}

void write_case(const std::filesystem::path& dir, const std::string& extra)
{
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "scalemesh.toml") << slurp("cases/tube/scalemesh.toml") << "\n" << extra;
}

TEST(Reproducible, OneThreadGivesByteIdenticalFilesAndTwoThreadsTheSame)
{
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / "tube";
    write_case(dir, "");
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--threads", "1"}).exit_code, 0);
    const auto first = outputs(dir);
    ASSERT_GE(first.size(), 10u);
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--threads", "1"}).exit_code, 0);
    EXPECT_EQ(differing(first, outputs(dir)), std::vector<std::string>{});
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--threads", "2"}).exit_code, 0);
    EXPECT_EQ(differing(first, outputs(dir)), std::vector<std::string>{});
    // The thread count reaches the report.
    const nlohmann::json report = nlohmann::json::parse(slurp(dir / "report.json"));
    EXPECT_EQ(report["parameters"]["threads"], 2);
}

TEST(Reproducible, MshFilesCarryVersionInputAndParameters)
{
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / "tube";
    write_case(dir, "");
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q"}).exit_code, 0);
    const nlohmann::json report = nlohmann::json::parse(slurp(dir / "report.json"));
    for (const char* name : {"mesh.msh", "surface.msh"}) {
        const std::string text = slurp(dir / name);
        const size_t begin = text.find("$EndMeshFormat\n$Comments\n");
        ASSERT_NE(begin, std::string::npos) << name;
        const std::string comments = text.substr(begin, text.find("$EndComments", begin) - begin);
        EXPECT_NE(comments.find("scalemesh " + report["scalemesh_version"].get<std::string>()), std::string::npos);
        EXPECT_NE(comments.find("input " + report["input"]["source"].get<std::string>()), std::string::npos);
        EXPECT_NE(comments.find("parameters K 4.2 M 7 "), std::string::npos) << comments;
    }
    // Gmsh still reads the volume mesh, and finds it valid.
    const CommandResult check = run_scalemesh({"check", (dir / "mesh.msh").string()});
    EXPECT_EQ(check.exit_code, 0) << check.err;
}

// Starts scalemesh, sends `signal` after `delay`, and waits for it.
int interrupted_run(const std::vector<std::string>& args, std::chrono::microseconds delay, int signal)
{
    std::vector<std::string> words = {std::getenv("SCALEMESH_BINARY")};
    words.insert(words.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& w : words) argv.push_back(w.data());
    argv.push_back(nullptr);
    pid_t pid = 0;
    if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
    std::this_thread::sleep_for(delay);
    ::kill(pid, signal);
    int status = 0;
    ::waitpid(pid, &status, 0);
    return status;
}

TEST(Interruption, LeavesNoPartialFileAndTheEarlierOutputsWholeOrAllNew)
{
    if (!std::getenv("SCALEMESH_BINARY")) GTEST_SKIP() << "run through ctest";
    const TempDir tmp;
    // The old outputs: the tube case. The new ones differ in every file
    // (M 5 changes every mesh, the inlet speed 0/U).
    const std::string changed = "[flow]\ninlet_speed = 0.2\n";
    const std::filesystem::path dir = tmp.path / "tube", fresh = tmp.path / "fresh" / "tube";
    write_case(dir, "");
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--threads", "1"}).exit_code, 0);
    const auto old_files = outputs(dir);
    std::string toml = slurp(dir / "scalemesh.toml");
    const size_t at = toml.find("M = 7");
    ASSERT_NE(at, std::string::npos) << "the tube case sets M = 7";
    toml.replace(at, 5, "M = 5");
    std::filesystem::create_directories(fresh);
    std::ofstream(fresh / "scalemesh.toml") << toml << "\n" << changed;
    const auto start = std::chrono::steady_clock::now();
    ASSERT_EQ(run_scalemesh({"run", fresh.string(), "-q", "--threads", "1"}).exit_code, 0);
    const auto duration = std::chrono::steady_clock::now() - start;
    const auto new_files = outputs(fresh);
    ASSERT_FALSE(differing(old_files, new_files).empty());

    // Signals spread over the whole run, from start-up to the final renames.
    int old_kept = 0, new_whole = 0;
    for (int k = 0; k <= 24; ++k) {
        std::ofstream(dir / "scalemesh.toml") << toml << "\n" << changed;
        const auto delay = std::chrono::duration_cast<std::chrono::microseconds>(duration * (k / 20.0));
        const int status = interrupted_run({"run", dir.string(), "-q", "--threads", "1"}, delay, k % 2 ? SIGTERM : SIGINT);
        for (const auto& entry : std::filesystem::recursive_directory_iterator(dir)) {
            EXPECT_EQ(entry.path().filename().string().find(".partial-"), std::string::npos)
                << entry.path() << " left after a signal at " << delay.count() << " us";
        }
        auto now = outputs(dir);
        if (differing(now, old_files).empty()) {
            ++old_kept;
        } else {
            EXPECT_EQ(differing(now, new_files), std::vector<std::string>{})
                << "a mixture of old and new outputs after a signal at " << delay.count() << " us (status " << status << ")";
            ++new_whole;
        }
        // Back to the old outputs for the next try.
        write_case(dir, "");
        if (!differing(now, old_files).empty()) {
            ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--threads", "1"}).exit_code, 0);
        }
    }
    std::printf("interruptions: earlier outputs untouched %d times, complete new outputs %d times\n", old_kept, new_whole);
    EXPECT_GT(old_kept, 0);
}

// A case directory holding only its case file: a run interrupted by SIGINT,
// SIGTERM or SIGHUP at any moment leaves either nothing of its own (no
// temporary file, no directory it made, such as an empty constant/polyMesh/)
// or all of its outputs.
TEST(Interruption, AFreshCaseGetsNothingOrEverything)
{
    ASSERT_NE(std::getenv("SCALEMESH_BINARY"), nullptr) << "run through ctest";
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / "tube";
    write_case(dir, "");
    const std::string toml = slurp(dir / "scalemesh.toml");
    const auto start = std::chrono::steady_clock::now();
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--threads", "1"}).exit_code, 0);
    const auto duration = std::chrono::steady_clock::now() - start;
    const auto complete = outputs(dir);
    const int signals[] = {SIGINT, SIGTERM, SIGHUP};
    int nothing = 0, everything = 0;
    for (int k = 0; k <= 15; ++k) {
        std::filesystem::remove_all(dir);
        std::filesystem::create_directories(dir);
        std::ofstream(dir / "scalemesh.toml") << toml;
        const auto delay = std::chrono::duration_cast<std::chrono::microseconds>(duration * (k / 12.0));
        const int status = interrupted_run({"run", dir.string(), "-q", "--threads", "1"}, delay, signals[k % 3]);
        std::vector<std::string> left;
        for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
            if (entry.path().filename() != "scalemesh.toml") left.push_back(std::filesystem::relative(entry.path(), dir));
        if (left.empty()) {
            ++nothing;
            continue;
        }
        EXPECT_EQ(differing(outputs(dir), complete), std::vector<std::string>{})
            << "signal " << signals[k % 3] << " at " << delay.count() << " us (status " << status << ") left "
            << left.front() << " and " << left.size() - 1 << " more";
        ++everything;
    }
    std::printf("interruptions of a fresh case: nothing left %d times, all outputs %d times\n", nothing, everything);
    EXPECT_GT(nothing, 0);
}

} // namespace
} // namespace scalemesh
