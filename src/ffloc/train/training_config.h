#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ffloc/core/error.h"

namespace ffloc {

// A setting that cannot make a run.
struct TrainingConfigProblem {
  std::string field;
  std::string message;
};

// InputError "<origin>: field '<field>': <message>" that keeps the field, so that a command can
// name the flag or the file that set it instead.
class TrainingConfigError : public InputError {
 public:
  TrainingConfigError(const std::string& origin, TrainingConfigProblem problem);
  const TrainingConfigProblem& problem() const { return problem_; }

 private:
  TrainingConfigProblem problem_;
};

// Everything that defines a training run. Defaults follow the paper's appendix where it gives a
// value (K = 5 mapping images, N in [250, 1000] map tokens, overlap in [0.2, 0.85], AdamW, cosine
// schedule with a linear warm-up, peak learning rate 1e-4, frozen encoder) and DUSt3R's recipe
// where it does not (alpha = 0.2, weight decay 0.05, betas (0.9, 0.95)).
struct TrainingConfig {
  // Initial weights, as `--model` elsewhere (model/model_loader.h): a FastForward or DUSt3R
  // checkpoint, or "random:<preset>[:<seed>]".
  std::string model = "random:tiny";
  uint64_t model_seed = 0;  // the untrained layers of a DUSt3R initialisation

  // Samples (training_sample.h).
  int mapping_frames = 5;
  int min_map_tokens = 250;
  int max_map_tokens = 1000;
  double min_overlap = 0.2;
  double max_overlap = 0.85;
  int overlap_candidates = 64;  // frames whose overlap with a query is measured per draw
  int overlap_stride = 4;       // pixel stride of the overlap measure
  int long_side = 512;          // preprocessing, as at inference
  double colour_jitter = 0.0;   // brightness/contrast/saturation factors in [1 - j, 1 + j]

  // Loss (confidence_loss.h).
  double alpha = 0.2;
  // The matching head's cross-entropy (matching_loss.h), for models that have one: its weight
  // beside Eq. 2, and the radius, in patch footprints at the patch's depth, within which a map
  // token's point counts as the patch's match.
  double match_weight = 1.0;
  double match_radius = 0.5;
  // Eq. 2 on the matching head's query points, beside the matching loss: soft-assigned points
  // pull the softmax towards averages of candidates, which PnP dislikes, so a run may weigh the
  // points less than the matches.
  double point_weight = 1.0;

  // Optimiser and schedule.
  int64_t steps = 1000;
  int64_t warmup_steps = 50;
  double learning_rate = 1e-4;
  double min_learning_rate = 1e-6;
  double weight_decay = 0.05;
  double beta1 = 0.9;
  double beta2 = 0.95;
  double adam_epsilon = 1e-8;
  double clip_grad_norm = 1.0;  // 0: no clipping
  bool train_encoder = false;
  // Name prefixes of the parameters training updates (e.g. "match_head."); empty: every
  // parameter (the encoder's only with train_encoder). The rest stay as loaded, and a frozen
  // decoder records no graph.
  std::vector<std::string> trained_parameters;

  // Batches (trainer.h): each optimiser step averages the loss over batch_size x accumulate x
  // the number of ranks samples, which share one map token count.
  int batch_size = 1;   // samples in one forward pass of one rank
  int accumulate = 1;   // forward passes whose gradients add up before a step
  int loader_threads = 1;     // background threads preparing samples (sample_prefetcher.h)
  int prefetch_samples = 8;   // samples prepared ahead of the network per rank

  uint64_t seed = 0;  // samples and augmentation; the only source of randomness in a run
  // Draws the validation samples, apart from `seed`, so runs with different seeds validate on
  // the same samples and their validation losses compare.
  uint64_t validation_seed = 0;
  int threads = 0;    // libtorch intra-op threads (0: all cores)
  std::string device = "cpu";
  // "fp32", or "bf16": mixed precision, with float32 weights, optimiser and loss and the network's
  // matrix products and convolutions in bfloat16 (autocast; train/autocast.h).
  std::string precision = "fp32";

  int64_t log_every = 10;
  int64_t checkpoint_every = 500;
  int keep_checkpoints = 2;
  int64_t validation_every = 0;  // 0: no validation
  int validation_samples = 8;

  // The first value that cannot make a run on this machine, if any; a caller that sets fields
  // from elsewhere (a command line) may name their source instead of the field.
  std::optional<TrainingConfigProblem> problem() const;
  // problem() but for what depends on the machine (a GPU for device cuda): a config file is
  // read with this, so that one naming cuda can run elsewhere with device overridden.
  std::optional<TrainingConfigProblem> settingsProblem() const;
  // TrainingConfigError for problem().
  void validate(const std::string& origin = "training config") const;
};

// Reads a JSON object of the fields above (any subset; the rest keep their defaults). Unknown
// keys, wrong types, and numbers that an integer field cannot hold exactly (1.5, 1e30, -1 for a
// seed) are InputErrors naming the file and the field.
TrainingConfig readTrainingConfig(const std::filesystem::path& file);
TrainingConfig trainingConfigFromJson(const nlohmann::json& json, const std::string& origin);
nlohmann::json toJson(const TrainingConfig& config);

// The first field of `a` (its JSON, toJson's or one with fields added) whose value `b` does not
// hold, `ignored` left out: what a resume, an optimizer state and the ranks of a run are held to.
std::optional<std::string> firstDifferingField(const nlohmann::json& a, const nlohmann::json& b,
                                               const std::set<std::string>& ignored = {});

}  // namespace ffloc
