#include "core/child_process.h"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace scalemesh {
namespace {

// The answer's first byte: what follows is the result, or what work threw.
constexpr char kResult = 'R';
constexpr char kThrew = 'E';

void write_all(int fd, const char* data, size_t size)
{
    for (size_t done = 0; done < size;) {
        const ssize_t n = ::write(fd, data + done, size - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return;
        done += static_cast<size_t>(n);
    }
}

[[noreturn]] void run_child(int fd, pid_t parent, const std::function<std::string()>& work)
{
    for (int s : {SIGINT, SIGTERM, SIGHUP}) std::signal(s, SIG_DFL);
    // Ended with its parent (an interrupted run's handler exits at once),
    // not left working for no one.
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);
    const rlimit no_core{0, 0};
    ::setrlimit(RLIMIT_CORE, &no_core);
    std::string answer(1, kResult);
    try {
        answer += work();
    } catch (const std::exception& e) {
        answer = std::string(1, kThrew) + e.what();
    } catch (...) {
        answer = std::string(1, kThrew) + "an exception that is not a std::exception";
    }
    write_all(fd, answer.data(), answer.size());
    ::close(fd);
    ::_exit(0);
}

// work's result, run in this process: what it throws as a child's would be.
std::string run_here(const std::function<std::string()>& work)
{
    try {
        return work();
    } catch (const std::exception& e) {
        throw ChildProcessError(e.what(), 0, 0);
    } catch (...) {
        throw ChildProcessError("an exception that is not a std::exception", 0, 0);
    }
}

} // namespace

std::string run_in_child_process(const std::function<std::string()>& work)
{
    int channel[2];
    if (::pipe(channel) != 0) return run_here(work);
    // Buffered output written once, not once more by the child's copy.
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid < 0) {
        ::close(channel[0]);
        ::close(channel[1]);
        return run_here(work);
    }
    if (pid == 0) {
        ::close(channel[0]);
        run_child(channel[1], parent, work);
    }
    ::close(channel[1]);
    std::string answer;
    char buffer[1 << 16];
    for (;;) {
        const ssize_t n = ::read(channel[0], buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        answer.append(buffer, static_cast<size_t>(n));
    }
    ::close(channel[0]);
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (WIFSIGNALED(status)) {
        const int signal = WTERMSIG(status);
        const char* name = ::strsignal(signal);
        throw ChildProcessError("was killed by signal " + std::to_string(signal) + " (" + (name ? name : "unknown") + ")",
                                signal, 0);
    }
    const int exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    if (answer.empty() || exit_status != 0)
        throw ChildProcessError("exited with status " + std::to_string(exit_status) + " without an answer", 0,
                                exit_status);
    if (answer[0] == kThrew) throw ChildProcessError(answer.substr(1), 0, 0);
    return answer.substr(1);
}

} // namespace scalemesh
