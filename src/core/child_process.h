#pragma once
// Work run in a process of its own, so that a crash inside a library the work
// calls (a segmentation fault or an abort in Gmsh's boundary recovery, say)
// ends that process and becomes an error of the run, which can then choose
// another way, instead of ending the run without a word.

#include <functional>
#include <stdexcept>
#include <string>

namespace scalemesh {

// The child ended without an answer. what() says how: the message of what
// `work` threw (threw()), or "was killed by signal 11 (Segmentation
// fault)" (signal() that signal), or "exited with status 1 without an
// answer" (exit_status() that status; as after a sanitizer's report).
class ChildProcessError : public std::runtime_error {
public:
    ChildProcessError(const std::string& what, bool threw, int signal, int exit_status)
        : std::runtime_error(what), threw_(threw), signal_(signal), exit_status_(exit_status)
    {
    }
    bool threw() const { return threw_; }
    int signal() const { return signal_; }
    int exit_status() const { return exit_status_; }
    // Killed from outside by an interrupt (SIGINT, SIGTERM, SIGHUP,
    // SIGQUIT: a terminal's Ctrl-C reaches the whole process group), not a
    // crash of its own: the caller should stop, not try another way.
    bool interrupted() const;

private:
    bool threw_;
    int signal_;
    int exit_status_;
};

// Runs `work` in a forked child process and returns the bytes it returned.
// Throws ChildProcessError when the child gives no answer (above). When no
// child can be made (pipe or fork fails), runs `work` in this process, where
// a crash is the process's and what it throws a ChildProcessError as well.
//
// The child is a copy of this process with the calling thread alone: `work`
// must not use a thread pool the process started (TBB; nor OpenMP, whose
// threads do not survive a fork once they ran: a library that has them must
// be held to one thread in the child), nor wait on a lock another thread
// may hold or that is held around this call (a recursive mutex this thread
// holds is held by no thread of the child's). What it changes stays in the
// child. The child ends with _exit (no atexit handlers or static
// destructors of the parent's, also when `work` calls exit), with SIGINT,
// SIGTERM, SIGHUP and SIGQUIT at their defaults (a handler of the parent's,
// which may remove the run's outputs, is not run there), no core file, and
// is killed when this thread ends first or this call leaves by an
// exception.
std::string run_in_child_process(const std::function<std::string()>& work);

} // namespace scalemesh
