#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "ffloc/eval/evaluator.h"
#include "ffloc/eval/oracle_depth_source.h"

namespace ffloc {

// One method of `ffloc eval --methods` (and the Python evaluate) run over a scene's queries.
struct MethodEvaluationOptions {
  EvaluationOptions evaluation;
  LocalizeOptions localize;  // the localizers' query options (evaluation.pnp and .verdict replace theirs)
  OracleDepthOptions oracle_depth;  // oracle-depth; its seed and sift-baseline's are localize.seed
  bool use_depth = true;            // classical: lift points with the mapping frames' depth
  // fastforward: a localizer over an in-memory map of the scene's mapping split. Left empty (a
  // build without the network), the method is unknown.
  std::function<std::unique_ptr<Localizer>(const Scene&)> fastforward;
};

// The method names evaluateMethod knows with these options.
std::vector<std::string> evaluationMethods(const MethodEvaluationOptions& options);

// What is wrong with a list of methods to evaluate ("names no method", "'classical' is given
// twice"), or "": an empty list ran the default without a word, and a method named twice ran twice.
std::string methodListProblem(const std::vector<std::string>& methods);

// "none of the methods evaluated (classical) uses it" when `setting` (a LocalizeOptions field one
// localization method alone uses, methodUsesSetting) matters to none of `methods`, or "": callers
// put the field or flag in front. Python's evaluate(methods=["classical"], features=500) and
// `ffloc eval --features 500` ran as if it were not given.
std::string settingNoMethodUsesProblem(const std::vector<std::string>& methods, const std::string& setting);

// oracle-depth and sift-baseline answer with correspondences (evaluate); classical and
// fastforward localize each query frame against a map of the mapping split built in memory
// (evaluateLocalizer), and `on_result` sees their results. InputError naming "methods" for an
// unknown method.
std::vector<FrameResult> evaluateMethod(const Scene& scene, const std::string& method,
                                        const MethodEvaluationOptions& options,
                                        const LocalizationObserver& on_result = nullptr);

}  // namespace ffloc
