#include "core/atomic_file.h"

#include "core/errors.h"

#include <array>
#include <atomic>
#include <csignal>
#include <cstring>
#include <thread>
#include <unistd.h>

namespace scalemesh {

namespace {

// A fixed table of pending temporary names, readable from a signal handler.
constexpr int kMaxPending = 64;
constexpr int kMaxName = 4096;
std::array<std::atomic<bool>, kMaxPending> g_in_use{};
std::array<std::array<char, kMaxName>, kMaxPending> g_names{};

int register_pending(const std::string& name)
{
    if (name.size() + 1 > kMaxName) return -1;
    for (int i = 0; i < kMaxPending; ++i) {
        bool expected = false;
        if (!g_in_use[i].load() && g_in_use[i].compare_exchange_strong(expected, true)) {
            std::memcpy(g_names[i].data(), name.c_str(), name.size() + 1);
            return i;
        }
    }
    return -1;
}

// The directories made for outputs not yet committed (created by
// AtomicOutput, missing before): removed again, when empty, with outputs that
// never came. A fixed table, readable from a signal handler.
std::array<std::atomic<bool>, kMaxPending> g_made_in_use{};
std::array<std::array<char, kMaxName>, kMaxPending> g_made{};

void register_made(const std::string& dir)
{
    if (dir.size() + 1 > kMaxName) return;
    for (int i = 0; i < kMaxPending; ++i) {
        bool expected = false;
        if (!g_made_in_use[i].load() && g_made_in_use[i].compare_exchange_strong(expected, true)) {
            std::memcpy(g_made[i].data(), dir.c_str(), dir.size() + 1);
            return;
        }
    }
}

// rmdir on every made directory that is empty; twice, so that a directory
// emptied by the first round (constant/ once polyMesh/ went) goes too.
// Async-signal-safe.
void remove_made_directories() noexcept
{
    for (int round = 0; round < 2; ++round)
        for (int i = 0; i < kMaxPending; ++i)
            if (g_made_in_use[i].load() && ::rmdir(g_made[i].data()) == 0) g_made_in_use[i].store(false);
}

void unregister_pending(int slot)
{
    if (slot >= 0) g_in_use[slot].store(false);
}

// commit_all's state, for a handler running on any thread: masking the
// signals holds them back only on the thread that commits, and the kernel
// hands a process-directed signal to any thread that does not mask it (a TBB
// worker), whose handler would remove the outputs not yet renamed. Below
// kIdle, -n: n handlers are acting on a signal (removing the pending outputs
// before the process ends), and no commit may start until they are done.
enum CommitState : int { kIdle, kCommitting, kSignalled };
std::atomic<int> g_commit_state{kIdle};
std::atomic<int> g_deferred_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "read from signal handlers");

} // namespace

AtomicOutput::AtomicOutput(std::filesystem::path path, bool make_directories) : path_(std::move(path))
{
    // The directories the output needs, made here so that an output that
    // never comes takes the ones it made along (never one that was there).
    std::vector<std::filesystem::path> missing;
    std::error_code ec;
    for (std::filesystem::path dir = std::filesystem::absolute(path_, ec).parent_path();
         make_directories && !dir.empty() && !std::filesystem::exists(dir, ec) && dir != dir.parent_path();
         dir = dir.parent_path())
        missing.push_back(dir);
    for (auto dir = missing.rbegin(); dir != missing.rend(); ++dir) {
        if (!std::filesystem::create_directory(*dir, ec) && ec)
            throw IoError(dir->string(), "cannot create the directory: " + ec.message());
        register_made(dir->string());
    }
    std::string name = path_.stem().string() + ".partial-" + std::to_string(::getpid()) + path_.extension().string();
    temporary_ = path_.parent_path() / name;
    slot_ = register_pending(std::filesystem::absolute(temporary_).string());
}

AtomicOutput::~AtomicOutput()
{
    if (!committed_) {
        std::error_code ignored;
        std::filesystem::remove(temporary_, ignored);
        remove_made_directories();
    }
    unregister_pending(slot_);
}

void AtomicOutput::commit()
{
    std::error_code ec;
    if (!std::filesystem::exists(temporary_, ec))
        throw IoError(path_.string(), "the writer produced no file");
    std::filesystem::rename(temporary_, path_, ec);
    if (ec) throw IoError(path_.string(), "cannot move the finished file into place: " + ec.message());
    committed_ = true;
}

void commit_or_stage(StagedOutputs& outputs, StagedOutputs* staged)
{
    if (!staged) return commit_all(outputs);
    for (auto& out : outputs) staged->push_back(std::move(out));
    outputs.clear();
}

void commit_all(StagedOutputs& outputs)
{
    sigset_t held, previous;
    sigemptyset(&held);
    sigaddset(&held, SIGINT);
    sigaddset(&held, SIGTERM);
    sigaddset(&held, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &held, &previous);
    g_deferred_signal.store(0);
    // A handler acting on another thread ends the process (or, in a test,
    // returns through signal_handled); the renames wait for it, so that it
    // never sees some outputs in place and others still pending.
    for (int expected = kIdle; !g_commit_state.compare_exchange_weak(expected, kCommitting); expected = kIdle)
        std::this_thread::yield();
    // Ends the commit: a signal another thread's handler deferred is raised
    // again, now on this thread and with no commit running.
    const auto finish = [&] {
        const int state = g_commit_state.exchange(kIdle);
        pthread_sigmask(SIG_SETMASK, &previous, nullptr);
        if (state == kSignalled) ::raise(g_deferred_signal.load());
    };
    try {
        for (auto& out : outputs) out->commit();
    } catch (...) {
        finish();
        throw;
    }
    // The directories made now hold committed outputs: they stay.
    for (auto& in_use : g_made_in_use) in_use.store(false);
    finish();
}

bool defer_signal_during_commit(int signal) noexcept
{
    for (;;) {
        int state = g_commit_state.load();
        if (state <= kIdle) {
            // No commit running: one more handler acting, and none starts.
            if (g_commit_state.compare_exchange_weak(state, state - 1)) return false;
            continue;
        }
        g_deferred_signal.store(signal);
        if (state == kSignalled || g_commit_state.compare_exchange_weak(state, kSignalled)) return true;
    }
}

void signal_handled() noexcept { g_commit_state.fetch_add(1); }

void remove_pending_outputs() noexcept
{
    for (int i = 0; i < kMaxPending; ++i)
        if (g_in_use[i].load()) ::unlink(g_names[i].data());
    remove_made_directories();
}

} // namespace scalemesh
