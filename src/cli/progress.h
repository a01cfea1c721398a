#pragma once
// What the command line shows while a run works, on stderr: one line per
// stage with its time, a live progress bar while a stage runs when stderr is
// a terminal, and a summary at the end of `scalemesh run`.

#include "pipeline/run_case.h"

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace scalemesh {

enum class Verbosity {
    Quiet,   // errors only
    Normal,  // a line per finished stage (name, seconds, one-line summary) and the final summary
    Verbose, // also a line when each stage starts, and per-stage details in the final summary
};

// Fraction in [0, 1] of the running stage that is done. The stages do not
// report fractions yet; a stage that gets this callback can, and the bar
// then fills instead of sweeping.
using ProgressCallback = std::function<void(double fraction)>;

class ProgressDisplay {
public:
    // `terminal`: draw a bar redrawn in place (\r) while a stage runs; otherwise
    // only whole lines are written, as a log file or a pipe wants them.
    // `expected_stages` sizes the overall bar (stages done of expected).
    ProgressDisplay(Verbosity verbosity, std::FILE* out, bool terminal, int expected_stages = 6);
    ~ProgressDisplay(); // stops the redraw thread and clears the bar
    ProgressDisplay(const ProgressDisplay&) = delete;
    ProgressDisplay& operator=(const ProgressDisplay&) = delete;

    // For run_pipeline and run_case: called at the start and end of each stage.
    StageListener listener();
    ProgressCallback callback();

    // Removes a bar being drawn, so that an error line starts at column 0.
    void clear();

    // The end of `scalemesh run`: cells, layers realised, worst quality,
    // time per stage, the files written. Nothing when quiet.
    void summary(const CaseConfig& config, const CaseResult& result, double seconds);

private:
    void stage_event(const StageTime& stage);
    void set_fraction(double fraction);
    void redraw_loop();
    void draw_locked();
    void clear_locked();

    Verbosity verbosity_;
    std::FILE* out_;
    bool terminal_;
    int expected_stages_;
    int stages_done_ = 0;

    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    bool bar_shown_ = false;
    std::string running_;  // name of the running stage; empty between stages
    double fraction_ = -1; // of the running stage; < 0 unknown
    std::chrono::steady_clock::time_point started_;
    std::thread redraw_;
};

} // namespace scalemesh
