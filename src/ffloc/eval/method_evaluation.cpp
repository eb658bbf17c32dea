#include "ffloc/eval/method_evaluation.h"

#include "ffloc/classical/classical_localizer.h"
#include "ffloc/classical/classical_mapper.h"
#include "ffloc/core/error.h"
#include "ffloc/data/splits.h"
#include "ffloc/eval/sift_baseline_source.h"
#include "ffloc/localization/localizer.h"

namespace ffloc {

std::vector<std::string> evaluationMethods(const MethodEvaluationOptions& options) {
  std::vector<std::string> methods = {"oracle-depth", "sift-baseline", "classical"};
  if (options.fastforward) methods.push_back("fastforward");
  return methods;
}

std::string methodListProblem(const std::vector<std::string>& methods) {
  if (methods.empty()) return "names no method";
  for (auto method = methods.begin(); method != methods.end(); ++method)
    if (std::find(methods.begin(), method, *method) != method) return "'" + *method + "' is given twice";
  return "";
}

std::string settingNoMethodUsesProblem(const std::vector<std::string>& methods, const std::string& setting) {
  const bool classical = methodUsesSetting(LocalizationMethod::kClassical, setting);
  const bool fastforward = methodUsesSetting(LocalizationMethod::kFastForward, setting);
  std::string names;
  for (const std::string& method : methods) {
    // oracle-depth and sift-baseline take the settings both localizers share (seed, solver) but
    // retrieval's (top_k, and the preset that sets it). A name none of them has is left to the
    // method list's own error, which names it.
    const bool known = method == "classical" || method == "fastforward" || method == "oracle-depth" ||
                       method == "sift-baseline";
    const bool retrieval = setting == "top_k" || setting == "preset";
    const bool uses = method == "classical"     ? classical
                      : method == "fastforward" ? fastforward
                                                : classical && fastforward && !retrieval;
    if (uses || !known) return "";
    names += (names.empty() ? "" : ", ") + method;
  }
  return "none of the methods evaluated (" + names + ") uses it";
}

std::vector<FrameResult> evaluateMethod(const Scene& scene, const std::string& method,
                                        const MethodEvaluationOptions& options,
                                        const LocalizationObserver& on_result) {
  // Before an in-memory map is built of no mapping frame: Python's evaluate blamed SIFT for it
  // ("fewer than two keypoints", an outside probe).
  requireSplits(scene);
  if (method == "oracle-depth") {
    OracleDepthOptions oracle = options.oracle_depth;
    oracle.seed = options.localize.seed;
    OracleDepthSource source(oracle);
    return evaluate(scene, source, options.evaluation);
  }
  if (method == "sift-baseline") {
    SiftBaselineOptions sift;
    sift.seed = options.localize.seed;
    SiftBaselineSource source(sift);
    return evaluate(scene, source, options.evaluation);
  }
  std::unique_ptr<Localizer> localizer;
  if (method == "classical") {
    ClassicalMappingOptions mapping;
    mapping.use_depth = options.use_depth;
    mapping.quiet = options.evaluation.quiet;
    ClassicalMap map = emptyClassicalMap(scene.metric, mapping);
    addToClassicalMap(map, scene, scene.mappingIndices(), mapping);
    localizer = std::make_unique<ClassicalLocalizer>(std::move(map));
  } else if (method == "fastforward" && options.fastforward) {
    localizer = options.fastforward(scene);
  } else {
    std::string known;
    for (const std::string& name : evaluationMethods(options)) known += (known.empty() ? "" : ", ") + name;
    throw InputError("methods: unknown method '" + method + "' (known: " + known + ")");
  }
  return evaluateLocalizer(scene, *localizer, method, options.localize, options.evaluation, on_result);
}

}  // namespace ffloc
