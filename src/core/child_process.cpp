#include "core/child_process.h"

#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <pthread.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace scalemesh {
namespace {

// The answer: a tag byte (what follows is the result, or what work threw),
// the length of what follows (8 bytes), then that many bytes.
constexpr char kResult = 'R';
constexpr char kThrew = 'E';
constexpr size_t kHeader = 1 + sizeof(uint64_t);

constexpr int kInterrupts[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};

bool write_all(int fd, const char* data, size_t size)
{
    for (size_t done = 0; done < size;) {
        const ssize_t n = ::write(fd, data + done, size - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        done += static_cast<size_t>(n);
    }
    return true;
}

std::string framed(char tag, const std::string& body)
{
    std::string answer(kHeader, tag);
    const uint64_t size = body.size();
    std::memcpy(&answer[1], &size, sizeof size);
    return answer + body;
}

[[noreturn]] void run_child(int fd, pid_t parent, const sigset_t& mask, const std::function<std::string()>& work)
{
    for (int s : kInterrupts) std::signal(s, SIG_DFL);
    ::pthread_sigmask(SIG_SETMASK, &mask, nullptr);
    // exit() from inside work ends the child here, before the parent's
    // atexit handlers (run last-registered first).
    std::atexit([] { ::_exit(2); });
    // Ended with its parent (an interrupted run's handler exits at once),
    // not left working for no one.
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);
    const rlimit no_core{0, 0};
    ::setrlimit(RLIMIT_CORE, &no_core);
    std::string answer;
    try {
        answer = framed(kResult, work());
    } catch (const std::exception& e) {
        answer = framed(kThrew, e.what());
    } catch (...) {
        answer = framed(kThrew, "an exception that is not a std::exception");
    }
    const bool sent = write_all(fd, answer.data(), answer.size());
    ::close(fd);
    ::_exit(sent ? 0 : 1);
}

// work's result, run in this process: what it throws as a child's would be.
std::string run_here(const std::function<std::string()>& work)
{
    try {
        return work();
    } catch (const std::exception& e) {
        throw ChildProcessError(e.what(), true, 0, 0);
    } catch (...) {
        throw ChildProcessError("an exception that is not a std::exception", true, 0, 0);
    }
}

// The parent's end of the pipe and the child, closed, killed and reaped on
// leaving by an exception.
struct Child {
    int fd = -1;
    pid_t pid = -1;
    Child() = default;
    Child(const Child&) = delete;
    Child& operator=(const Child&) = delete;
    ~Child()
    {
        if (fd >= 0) ::close(fd);
        if (pid > 0) {
            ::kill(pid, SIGKILL);
            while (::waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {
            }
        }
    }
};

} // namespace

bool ChildProcessError::interrupted() const
{
    for (int s : kInterrupts)
        if (signal_ == s) return true;
    return false;
}

std::string run_in_child_process(const std::function<std::string()>& work)
{
    int channel[2];
    if (::pipe2(channel, O_CLOEXEC) != 0) return run_here(work);
    // Buffered output written once, not once more by the child's copy.
    std::fflush(stdout);
    std::fflush(stderr);
    // No signal handled between the fork and the child's own handlers.
    sigset_t all, mask;
    sigfillset(&all);
    ::pthread_sigmask(SIG_SETMASK, &all, &mask);
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::close(channel[0]);
        run_child(channel[1], parent, mask, work);
    }
    ::pthread_sigmask(SIG_SETMASK, &mask, nullptr);
    ::close(channel[1]);
    if (pid < 0) {
        ::close(channel[0]);
        return run_here(work);
    }
    Child child;
    child.fd = channel[0];
    child.pid = pid;
    std::string answer;
    char buffer[1 << 16];
    for (;;) {
        const ssize_t n = ::read(child.fd, buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        answer.append(buffer, static_cast<size_t>(n));
    }
    int status = 0;
    pid_t reaped;
    while ((reaped = ::waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
    }
    child.pid = -1;
    // A whole answer stands, however the child's end is told (a host that
    // reaps every child leaves waitpid nothing to report).
    uint64_t size = 0;
    if (answer.size() >= kHeader) std::memcpy(&size, &answer[1], sizeof size);
    if (answer.size() >= kHeader && answer.size() - kHeader == size) {
        const bool threw = answer[0] == kThrew;
        answer.erase(0, kHeader);
        if (threw) throw ChildProcessError(answer, true, 0, 0);
        return answer;
    }
    if (reaped == pid && WIFSIGNALED(status)) {
        const int signal = WTERMSIG(status);
        const char* name = ::strsignal(signal);
        throw ChildProcessError("was killed by signal " + std::to_string(signal) + " (" + (name ? name : "unknown") + ")",
                                false, signal, 0);
    }
    const int exit_status = reaped == pid && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    throw ChildProcessError(exit_status >= 0 ? "exited with status " + std::to_string(exit_status) + " without an answer"
                                             : "ended without an answer",
                            false, 0, exit_status);
}

} // namespace scalemesh
