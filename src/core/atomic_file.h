#pragma once
// Output files are written under a temporary name in the target directory and
// renamed into place only when complete, so no half-written file is ever left
// where a user or the next tool would read it.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace scalemesh {

class AtomicOutput {
public:
    // The temporary name keeps the extension of `path`, since some writers
    // (the Gmsh SDK) choose the format from it. With make_directories, the
    // missing directories on the way to `path` are made (IoError when that
    // fails), and removed again, where empty, when the output never comes
    // (the destructor without a commit, or remove_pending_outputs); without
    // it, a missing directory is the writer's IoError.
    explicit AtomicOutput(std::filesystem::path path, bool make_directories = false);
    ~AtomicOutput(); // removes the temporary file unless committed
    AtomicOutput(const AtomicOutput&) = delete;
    AtomicOutput& operator=(const AtomicOutput&) = delete;

    const std::filesystem::path& temporary() const { return temporary_; }
    const std::filesystem::path& path() const { return path_; }

    // Renames the temporary file onto the final path. Throws IoError.
    void commit();

private:
    std::filesystem::path path_;
    std::filesystem::path temporary_;
    bool committed_ = false;
    int slot_ = -1;
};

// Outputs written under temporary names, moved into place together.
using StagedOutputs = std::vector<std::unique_ptr<AtomicOutput>>;

// Commits every output with SIGINT, SIGTERM and SIGHUP held back, so that an
// interruption leaves either all of them in place or none (the renames take
// microseconds; a held signal is delivered when they are done). Throws
// IoError as AtomicOutput::commit. A signal handler must call
// defer_signal_during_commit first: the mask holds signals back only on the
// committing thread.
void commit_all(StagedOutputs& outputs);

// For a writer asked to hand its outputs over: moves them into `staged`,
// still uncommitted, when given; commits them (commit_all) otherwise.
void commit_or_stage(StagedOutputs& outputs, StagedOutputs* staged);

// For signal handlers, on any thread: while commit_all runs, records the
// signal for commit_all to raise again when it is done and returns true (the
// handler then returns at once); otherwise returns false, and no commit
// starts until the process ends or the handler calls signal_handled.
bool defer_signal_during_commit(int signal) noexcept;

// For a handler that acted on a signal (defer_signal_during_commit returned
// false) and returns instead of ending the process: commits may start again.
void signal_handled() noexcept;

// Removes every temporary file still pending, and the directories made for
// them that are empty; safe to call from a signal handler (uses only unlink
// and rmdir on pre-built names).
void remove_pending_outputs() noexcept;

} // namespace scalemesh
