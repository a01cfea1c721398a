#pragma once
// Work run in a process of its own, so that a crash inside a library the work
// calls (a segmentation fault or an abort in Gmsh's boundary recovery, say)
// ends that process and becomes an error of the run, which can then choose
// another way, instead of ending the run without a word.

#include <functional>
#include <stdexcept>
#include <string>

namespace scalemesh {

// The child ended without an answer: `work` threw (signal() == 0, what() is
// its exception's), or the child died (signal() is the signal that killed
// it, or 0 with exit_status() its status when it exited without answering,
// as after a sanitizer's report; what() then says so: "was killed by signal
// 11 (Segmentation fault)", "exited with status 1 without an answer").
class ChildProcessError : public std::runtime_error {
public:
    ChildProcessError(const std::string& what, int signal, int exit_status)
        : std::runtime_error(what), signal_(signal), exit_status_(exit_status)
    {
    }
    int signal() const { return signal_; }
    int exit_status() const { return exit_status_; }

private:
    int signal_;
    int exit_status_;
};

// Runs `work` in a forked child process and returns the bytes it returned.
// Throws ChildProcessError when the child gives no answer (above). When no
// child can be made (fork or pipe fails), runs `work` in this process, where
// a crash is the process's and what it throws a ChildProcessError as well.
//
// The child is a copy of this process with the calling thread alone: `work`
// must not use a thread pool the process started (TBB, OpenMP) nor wait on a
// lock another thread may hold; what it changes stays in the child. The
// child ends with _exit (no atexit handlers, no static destructors), with
// SIGINT, SIGTERM and SIGHUP at their defaults (a handler of the parent's,
// which may remove the run's outputs, is not run there) and no core file;
// it is killed when this process ends first.
std::string run_in_child_process(const std::function<std::string()>& work);

} // namespace scalemesh
