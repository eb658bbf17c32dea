#include "bench_report.h"

#ifdef FFLOC_WITH_TORCH

#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "bench_sgemm.h"
#include "ffloc/model/model_options.h"

namespace ffloc::cli {
namespace {

void printJson(const nlohmann::json& object) {
  std::printf("%s\n", object.dump().c_str());
  std::fflush(stdout);
}

// By the precision, not its spelling: --dtype f32 lost the reference's fp32 rows.
const ReferenceRow* findRow(const std::map<std::string, ReferenceRow>* rows, const std::string& dtype) {
  if (!rows) return nullptr;
  for (const auto& [name, row] : *rows)
    if (parseNetworkDtype(name) == parseNetworkDtype(dtype)) return &row;
  return nullptr;
}

}  // namespace

BenchReport::BenchReport(Setup setup, std::optional<ReferenceTiming> reference)
    : setup_(std::move(setup)), reference_(std::move(reference)) {}

bool BenchReport::comparable() const {
  return reference_ && setup_.config == kReferenceConfig && setup_.width == kReferenceWidth &&
         setup_.height == kReferenceHeight;
}

void BenchReport::header() const {
  if (setup_.json) return;
  std::printf("%-5s %-40s %9s %17s %8s %8s %6s   %-28s %s\n", "dtype", "what", "median s", "(min..max)", "GFLOP",
              "GFLOP/s", "sgemm", "Python s (runs; pooled)", "ffloc/Python");
  std::fflush(stdout);
}

void BenchReport::sgemm(double gflops, double seconds_measured) {
  sgemm_gflops_ = gflops;
  if (setup_.json) {
    printJson({{"row", "sgemm"}, {"dtype", "fp32"}, {"threads", setup_.threads},
               {"shape", {kSgemmM, kSgemmK, kSgemmN}}, {"gflops", gflops}, {"load_average", loadAverage()}});
    return;
  }
  std::printf("sgemm %dx%d by %dx%d, %d threads: %.1f GFLOP/s (measured in %.1f s); the sgemm column is each "
              "row's GFLOP/s as a share of it\n",
              kSgemmM, kSgemmK, kSgemmK, kSgemmN, setup_.threads, gflops, seconds_measured);
}

void BenchReport::row(const std::string& dtype, const std::string& what, const Timing& timing, double flops,
                      const std::map<std::string, ReferenceRow>* reference_rows) const {
  const double gflops = flops * 1e-9 / timing.median();
  const double share = sgemm_gflops_ > 0.0 ? gflops / sgemm_gflops_ : 0.0;
  if (setup_.json) {
    printJson({{"row", what}, {"dtype", dtype}, {"threads", setup_.threads}, {"median_s", timing.median()},
               {"min_s", timing.min()}, {"max_s", timing.max()}, {"calls_s", timing.seconds},
               {"gflop", flops * 1e-9}, {"gflops", gflops}, {"sgemm_share", share},
               {"load_average", loadAverage()}});
    return;
  }
  char range[64];
  std::snprintf(range, sizeof(range), "(%.3f..%.3f)", timing.min(), timing.max());
  std::printf("%-5s %-40s %9.3f %17s %8.1f %8.1f %5.0f%%", dtype.c_str(), what.c_str(), timing.median(), range,
              flops * 1e-9, gflops, 100.0 * share);
  if (const ReferenceRow* reference = findRow(reference_rows, dtype)) {
    std::string runs;
    if (!reference->process_medians.empty()) {
      const auto [low, high] =
          std::minmax_element(reference->process_medians.begin(), reference->process_medians.end());
      char text[48];
      std::snprintf(text, sizeof(text), "%.2f-%.2f", *low, *high);
      runs = text;
    }
    char pooled[32] = "";
    if (reference->pooled_median) std::snprintf(pooled, sizeof(pooled), "; %.2f", *reference->pooled_median);
    std::printf("   %-28s", (runs + pooled).c_str());
    std::optional<double> base = reference->pooled_median;
    if (!base && !reference->process_medians.empty()) base = Timing{reference->process_medians}.median();
    if (base) std::printf(" %.2f", timing.median() / *base);
  }
  std::printf("\n");
  std::fflush(stdout);
}

void BenchReport::memory(const std::string& dtype, const std::string& model, const MemoryReport& memory) const {
  if (setup_.json) {
    printJson({{"row", model + " memory"}, {"dtype", dtype}, {"threads", setup_.threads},
               {"rss_after_build_mib", memory.after_build_mib}, {"peak_rss_mib", memory.peak_mib},
               {"peak_is_per_model", memory.peak_is_per_model}});
    return;
  }
  std::printf("%-5s %-40s RSS after building %.0f MiB, peak while timing %.0f MiB%s\n", dtype.c_str(),
              (model + " memory").c_str(), memory.after_build_mib, memory.peak_mib,
              memory.peak_is_per_model ? "" : " (process-wide ru_maxrss)");
  std::fflush(stdout);
}

void BenchReport::profile(const std::string& dtype, const std::string& what, double call_seconds,
                          const OpProfile& profile) const {
  double attributed = 0.0;
  for (const OpTotals& totals : profile) attributed += totals.seconds;
  if (setup_.json) {
    nlohmann::json kinds = nlohmann::json::array();
    for (size_t i = 0; i < profile.size(); ++i) {
      kinds.push_back({{"kind", opKindName(static_cast<OpKind>(i))}, {"seconds", profile[i].seconds},
                       {"gflop", profile[i].flops * 1e-9}, {"calls", profile[i].calls}});
    }
    printJson({{"profile", what}, {"dtype", dtype}, {"threads", setup_.threads}, {"call_s", call_seconds},
               {"kinds", kinds}});
    return;
  }
  std::printf("      profile of one call: %.3f s, of which outside the kinds below %.3f s\n", call_seconds,
              call_seconds - attributed);
  for (size_t i = 0; i < profile.size(); ++i) {
    const OpTotals& totals = profile[i];
    if (totals.calls == 0) continue;
    std::printf("      %-22s %8.3f s %5.1f%% %6lld calls", opKindName(static_cast<OpKind>(i)), totals.seconds,
                100.0 * totals.seconds / call_seconds, static_cast<long long>(totals.calls));
    if (totals.flops > 0.0) {
      std::printf(" %8.1f GFLOP %6.1f GFLOP/s", totals.flops * 1e-9, totals.flops * 1e-9 / totals.seconds);
    }
    std::printf("\n");
  }
  std::fflush(stdout);
}

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
