#include "cli/progress.h"

#include <algorithm>
#include <cmath>

namespace scalemesh {

namespace {

// A stage shorter than this never shows a bar: the line at its end says all.
constexpr auto kBarDelay = std::chrono::milliseconds(300);
constexpr auto kRedrawPeriod = std::chrono::milliseconds(100);
constexpr int kBarWidth = 30;

std::string seconds_text(double s)
{
    char text[32];
    std::snprintf(text, sizeof text, "%.2f s", s);
    return text;
}

} // namespace

ProgressDisplay::ProgressDisplay(Verbosity verbosity, std::FILE* out, bool terminal, int expected_stages)
    : verbosity_(verbosity), out_(out), terminal_(terminal && verbosity != Verbosity::Quiet),
      expected_stages_(std::max(1, expected_stages))
{
    if (terminal_) redraw_ = std::thread([this] { redraw_loop(); });
}

ProgressDisplay::~ProgressDisplay()
{
    {
        std::lock_guard lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    if (redraw_.joinable()) redraw_.join();
    clear();
}

StageListener ProgressDisplay::listener()
{
    return [this](const StageTime& stage) { stage_event(stage); };
}

ProgressCallback ProgressDisplay::callback()
{
    return [this](double fraction) { set_fraction(fraction); };
}

void ProgressDisplay::clear()
{
    std::lock_guard lock(mutex_);
    clear_locked();
}

void ProgressDisplay::stage_event(const StageTime& stage)
{
    std::lock_guard lock(mutex_);
    if (verbosity_ == Verbosity::Quiet) return;
    clear_locked();
    if (stage.seconds < 0) {
        running_ = stage.name;
        fraction_ = -1;
        started_ = std::chrono::steady_clock::now();
        if (verbosity_ == Verbosity::Verbose) std::fprintf(out_, "scalemesh: %s ...\n", stage.name.c_str());
    } else {
        running_.clear();
        ++stages_done_;
        std::fprintf(out_, "scalemesh: %-10s %7.2f s  %s\n", stage.name.c_str(), stage.seconds, stage.summary.c_str());
    }
    std::fflush(out_);
}

void ProgressDisplay::set_fraction(double fraction)
{
    std::lock_guard lock(mutex_);
    if (std::isfinite(fraction)) fraction_ = std::clamp(fraction, 0.0, 1.0);
}

void ProgressDisplay::redraw_loop()
{
    std::unique_lock lock(mutex_);
    while (!stop_) {
        wake_.wait_for(lock, kRedrawPeriod);
        if (stop_) break;
        if (!running_.empty() && std::chrono::steady_clock::now() - started_ >= kBarDelay) draw_locked();
    }
}

// "[#######>......] sizing 3/6  12.3 s": the bar fills with the stage's
// fraction when it reports one; otherwise it shows the stages done and a
// marker sweeping along it, so a long stage is seen to be alive.
void ProgressDisplay::draw_locked()
{
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    std::string bar(kBarWidth, '.');
    if (fraction_ >= 0) {
        std::fill_n(bar.begin(), static_cast<int>(std::lround(fraction_ * kBarWidth)), '#');
    } else {
        // A retried stage makes the run longer than expected: never show it done.
        const int expected = std::max(expected_stages_, stages_done_ + 1);
        const int done = kBarWidth * stages_done_ / expected;
        std::fill_n(bar.begin(), done, '#');
        const int span = kBarWidth - done;
        if (span > 0) {
            const int step = static_cast<int>(elapsed / 0.1) % (2 * span);
            bar[done + (step < span ? step : 2 * span - 1 - step)] = '>';
        }
    }
    std::string text = "\rscalemesh: [" + bar + "] " + running_;
    if (fraction_ >= 0) text += " " + std::to_string(static_cast<int>(std::lround(100 * fraction_))) + "%";
    else text += " (stage " + std::to_string(stages_done_ + 1) + ")";
    text += "  " + seconds_text(elapsed) + "\033[K";
    std::fputs(text.c_str(), out_);
    std::fflush(out_);
    bar_shown_ = true;
}

void ProgressDisplay::clear_locked()
{
    if (!bar_shown_) return;
    std::fputs("\r\033[K", out_);
    std::fflush(out_);
    bar_shown_ = false;
}

void ProgressDisplay::summary(const CaseConfig& config, const CaseResult& result, double seconds)
{
    std::lock_guard lock(mutex_);
    if (verbosity_ == Verbosity::Quiet) return;
    clear_locked();
    const PipelineRun& run = result.run;
    std::FILE* o = out_;
    std::fprintf(o, "scalemesh: done in %s\n", seconds_text(seconds).c_str());
    const SurfaceFacts surface = surface_facts(final_surface(run));
    std::fprintf(o, "  surface   %lld triangles, %lld points, %lld component%s, Euler characteristic %lld\n",
                 static_cast<long long>(surface.triangles), static_cast<long long>(surface.vertices),
                 static_cast<long long>(surface.components), surface.components == 1 ? "" : "s",
                 static_cast<long long>(surface.euler_characteristic));
    if (run.volume) {
        const VolumeResult& v = *run.volume;
        const QualityReport& q = v.after_slivers;
        std::fprintf(o, "  cells     %lld tetrahedra, %lld points", static_cast<long long>(v.mesh.tets.size()),
                     static_cast<long long>(v.mesh.points.size()));
        if (result.polymesh)
            std::fprintf(o, "; OpenFOAM: %lld cells, %lld of them layer prisms (%.1f%% of wall faces x layers intact)",
                         static_cast<long long>(result.polymesh->cells), static_cast<long long>(result.layer_prisms),
                         100 * intact_prism_share(result));
        std::fprintf(o, "\n");
        const LayerAccount& a = v.layers;
        std::fprintf(o, "  layers    %lld of %lld wall nodes with D >= L_min keep all %d layers (%.2f%%), %.2f on average",
                     static_cast<long long>(a.eligible_full), static_cast<long long>(a.eligible_nodes), a.layermaking,
                     100 * a.coverage(), a.eligible_mean);
        if (a.opening_nodes)
            std::fprintf(o, "; %lld opening nodes (cap rings carry their layers)", static_cast<long long>(a.opening_nodes));
        std::fprintf(o, "\n");
        if (result.tet_cells) {
            // Prism layers written as prism cells: the quality the floors
            // judge, of the tets written as cells of their own (a prism's
            // own tets are as flat as its layer is thin), and OpenFOAM's
            // worst face.
            const CellFloors& c = *result.tet_cells;
            std::fprintf(o,
                         "  quality   worst aspect ratio %.4f, %.3f%% below 0.1, smallest dihedral angle %.2f deg (the "
                         "tet cells; the layer prisms are cells of their own), largest non-orthogonality %.3f deg\n",
                         c.min_aspect_ratio, 100 * c.fraction_below_0_1, c.min_dihedral_deg,
                         std::floor(1000 * result.openfoam_checks.max_non_orthogonality_deg) / 1000);
        } else {
            std::fprintf(o,
                         "  quality   worst aspect ratio %.4f, mean %.4f, %.3f%% below 0.1, smallest dihedral angle %.2f "
                         "deg, largest non-orthogonality %.3f deg\n",
                         q.min_aspect_ratio, q.mean_aspect_ratio, 100 * q.fraction_below_0_1, q.min_dihedral_deg,
                         std::floor(1000 * v.max_non_orthogonality_deg) / 1000); // cut: 69.9999 is not 70.000
        }
        if (verbosity_ == Verbosity::Verbose) {
            const auto phase = [o](const char* name, const QualityReport& r) {
                std::fprintf(o, "            %-21s %9lld tets, worst %.4f, %.3f%% below 0.1, %lld below 0.02\n", name,
                             static_cast<long long>(r.tets), r.min_aspect_ratio, 100 * r.fraction_below_0_1,
                             static_cast<long long>(r.below_0_02));
            };
            std::string losses;
            for (int k = 1; k < kLayerLossKinds; ++k)
                if (v.layers.eligible_losses[k])
                    losses += (losses.empty() ? "" : ", ") + std::to_string(v.layers.eligible_losses[k]) + " " +
                              layer_loss_name(static_cast<LayerLoss>(k));
            if (!losses.empty()) std::fprintf(o, "            first missing layer: %s\n", losses.c_str());
            phase("before flips", v.before_flips);
            phase("after flips", v.after_flips);
            phase("after sliver removal", v.after_slivers);
            std::fprintf(o, "            flips 3-2 %lld, 2-3 %lld, 4-4 %lld; median first-layer anisotropy %.2f\n",
                         static_cast<long long>(v.flips_32), static_cast<long long>(v.flips_23),
                         static_cast<long long>(v.flips_44), v.first_layer_anisotropy_median);
            std::fprintf(o, "            surface quads split the other way %lld: %lld re-triangulated, %lld diagonals "
                            "flipped; %lld other surface edges flipped to Delaunay facets; %lld flat surface caps "
                            "peeled; %lld cap diagonals flipped for tets below the floors, %lld for light faces; "
                            "insertion retries %lld\n",
                         static_cast<long long>(v.surface_quads), static_cast<long long>(v.surface_quads - v.quad_flips),
                         static_cast<long long>(v.quad_flips), static_cast<long long>(v.facet_flips),
                         static_cast<long long>(v.caps_peeled), static_cast<long long>(v.poor_tet_cap_flips),
                         static_cast<long long>(v.light_face_cap_flips),
                         static_cast<long long>(v.insertion_retries));
        }
    } else {
        std::fprintf(o, "  cells     no volume mesh ([remeshing] cycles = 0 or [volume] enabled = false)\n");
    }
    if (verbosity_ == Verbosity::Verbose) {
        if (run.sizing) {
            const auto [lo, hi] = std::minmax_element(run.sizing->d.begin(), run.sizing->d.end());
            std::fprintf(o, "  sizing    K %g, M %g, G %g, L_min %.4g mm, L_max %.4g mm; d in [%.4g, %.4g] mm\n", config.K,
                         config.M, config.G, run.L_min, run.L_max, *lo, *hi);
        }
        for (const PipelineRun::Refinement& r : run.refinements)
            std::fprintf(o, "  retry %d   %lld failing nodes, d reduced at %lld points\n", r.attempt,
                         static_cast<long long>(r.failing_nodes), static_cast<long long>(r.refined_points));
    }
    std::string times;
    for (const StageTime& s : run.stages) times += (times.empty() ? "" : ", ") + s.name + " " + seconds_text(s.seconds);
    std::fprintf(o, "  time      %s\n", times.c_str());
    std::string files;
    for (const auto& p : result.written)
        files += (files.empty() ? "" : " ") + std::filesystem::relative(p, config.directory).string();
    std::fprintf(o, "  wrote     %s (in %s)\n", files.c_str(), config.directory.string().c_str());
    if (!result.removed.empty()) {
        std::string stale;
        for (const auto& p : result.removed)
            stale += (stale.empty() ? "" : " ") + std::filesystem::relative(p, config.directory).string();
        // The count first: a name such as OpenFOAM's "0" would read as one.
        std::fprintf(o, "  removed   %zu earlier output%s this run did not write: %s\n", result.removed.size(),
                     result.removed.size() == 1 ? "" : "s", stale.c_str());
    }
    if (result.orphaned_partials > 0)
        std::fprintf(o, "  removed   %lld unfinished outputs of runs that were killed\n",
                     static_cast<long long>(result.orphaned_partials));
    std::fflush(o);
}

} // namespace scalemesh
