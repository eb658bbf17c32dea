#pragma once

#ifdef FFLOC_WITH_TORCH

#include <map>
#include <optional>
#include <string>

#include "bench_measurement.h"
#include "bench_reference.h"
#include "ffloc/model/op_profile.h"

namespace ffloc::cli {

// What `ffloc bench model` prints: a table for people, or with `json` one JSON object per line
// (rows, memory, the sgemm rate, profiles) for scripts/bench.sh.
class BenchReport {
 public:
  struct Setup {
    std::string config;
    int64_t width = 0, height = 0;
    int threads = 0;
    bool json = false;
  };

  BenchReport(Setup setup, std::optional<ReferenceTiming> reference);

  void header() const;
  // The machine's sgemm rate, the denominator of every row's sgemm_share.
  void sgemm(double gflops, double seconds_measured);
  // reference_rows: the Python reference's rows for this measurement, or null.
  void row(const std::string& dtype, const std::string& what, const Timing& timing, double flops,
           const std::map<std::string, ReferenceRow>* reference_rows) const;
  void memory(const std::string& dtype, const std::string& model, const MemoryReport& memory) const;
  // One call of a row with the per-kind totals of model/op_profile.h.
  void profile(const std::string& dtype, const std::string& what, double call_seconds, const OpProfile& profile) const;

  const std::map<std::string, ReferenceRow>* encoderReference() const { return comparable() ? &reference_->encoder : nullptr; }
  const std::map<std::string, ReferenceRow>* pairReference() const { return comparable() ? &reference_->pair : nullptr; }
  bool hasReference() const { return reference_.has_value(); }
  // Whether the reference measured this setup (large config, 512x384); other setups get no ratio.
  bool comparable() const;
  const std::filesystem::path& referencePath() const { return reference_->path; }
  bool json() const { return setup_.json; }

 private:
  Setup setup_;
  std::optional<ReferenceTiming> reference_;
  double sgemm_gflops_ = 0.0;
};

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
