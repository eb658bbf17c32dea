#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/map_camera.h"
#include "ffloc/geometry/pose.h"
#include "ffloc/localization/verdict.h"
#include "ffloc/pose/pnp.h"
#include "ffloc/retrieval/global_descriptor.h"
#include "ffloc/retrieval/image_selection.h"

namespace ffloc {

// How a map is turned into a pose. Each method writes its own kind of map (`ffloc map
// --method`), and a map localizes with the method it was built with.
enum class LocalizationMethod { kClassical, kFastForward };
const char* toString(LocalizationMethod method);                     // "classical", "fastforward"
LocalizationMethod parseLocalizationMethod(const std::string& name);  // InputError naming "method"

// Whether `method` uses the query setting `field` (QuerySettings' names, and "model" and "dtype"
// for the network): FastForward alone uses features, selection, retrieval, verify, model and
// dtype, the classical method alone pose_guided, both the rest. A setting the map's method would
// ignore is refused by the CLI and the Python bindings alike.
bool methodUsesSetting(LocalizationMethod method, const std::string& field);

// Where FastForward takes its K mapping images from: the global descriptor pooled from encoder
// tokens, or the classical VLAD descriptor stored beside them.
// How FastForward ranks the mapping images: by the pooled encoder tokens, by the classical VLAD
// of sparse SIFT (maps built with VLAD), or by a VLAD of the encoder's tokens (pipeline/token_vlad.h).
enum class FastForwardRetrieval { kEncoder, kVlad, kTokenVlad };
const char* toString(FastForwardRetrieval retrieval);                     // "encoder", "vlad", "token-vlad"
FastForwardRetrieval parseFastForwardRetrieval(const std::string& name);  // InputError naming "retrieval"

// One query's options. Fields marked with a method are read by that method only.
struct LocalizeOptions {
  size_t top_k = 10;  // K mapping images matched (classical) or behind the map representation
  uint64_t seed = 0;  // RANSAC, token sampling, random image selection
  PnpOptions pnp;
  VerdictOptions verdict;

  int64_t num_features = 1500;  // FastForward: N map tokens sampled from the K images
  ImageSelection selection = ImageSelection::kRetrieval;           // FastForward
  // FastForward. The token VLAD ranked better than the pooled tokens and localised more queries
  // on both of the model card's sets (docs/pipeline.md, "Retrieval").
  FastForwardRetrieval retrieval = FastForwardRetrieval::kTokenVlad;
  int long_side = 0;                   // FastForward: of the preprocessed query, 0: the map's
  GlobalDescriptorOptions descriptor;  // FastForward: must match the mapper's
  // FastForward: predict a second time with the second-ranked image as the reference frame and
  // compare the poses (the verdict's agreement test). Doubles the network time.
  bool verify_with_second_reference = true;
  // Classical: when the first pose is not `localized`, also match the top_k mapping images that
  // pose sees (beyond those retrieval chose) and estimate again; when that is not `localized`
  // either, add the looser matches the pose places close to their keypoints and estimate once
  // more. Far and opposite views, which retrieval ranks poorly, gain most (docs/classical.md); a
  // localized query pays nothing.
  bool pose_guided_retrieval = true;
  // Asked between the stages of a query (after the query's features, after a network pass,
  // before PnP, before and after a second look); when it answers true, localize() stops there
  // with QueryStopped. The server asks
  // whether the query's client is still connected. Empty: a query always runs to its end.
  std::function<bool()> stop_requested;

  // The paper's settings: "indoor" K = 10, N = 1500; "outdoor" K = 20, N = 3000. InputError
  // naming "preset" for other names.
  static LocalizeOptions preset(const std::string& name);
  // InputError naming the field (top_k, num_features, pnp.inlier_threshold_px, ...) for a value
  // out of range or NaN.
  void check() const;
};

// A query's options as a user names them (the CLI's flags, the Python keyword arguments): a
// preset, then overrides. top_k and features replace the preset's only when given.
struct QuerySettings {
  std::string preset = "indoor";
  std::optional<int64_t> top_k;
  std::optional<int64_t> features;
  uint64_t seed = 0;  // RANSAC, token sampling and random selection alike
  std::string selection = "retrieval";
  std::string retrieval = "token-vlad";
  std::string solver = "lo-ransac";
  bool verify = true;  // LocalizeOptions::verify_with_second_reference
  bool pose_guided = true;  // LocalizeOptions::pose_guided_retrieval
};
// The checked options. InputError naming the field (preset, top_k, selection, retrieval, ...).
LocalizeOptions localizeOptions(const QuerySettings& settings);

// Thrown by Localizer::localize when LocalizeOptions::stop_requested answered true; what()
// names the stage the query stopped at.
class QueryStopped : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
// Throws QueryStopped ("stopped <stage>") when `options` ask for it; for localizers between
// their stages.
void stopIfRequested(const LocalizeOptions& options, const std::string& stage);

// Wall-clock seconds of each stage of one query.
struct QueryTimings {
  double preprocessing = 0;  // image reading aside: undistortion, resize, crop
  double features = 0;       // the query's encoder pass or SIFT
  double retrieval = 0;      // global descriptor and image selection
  double matching = 0;       // map assembly, decoder and heads / descriptor matching, back to world
  double pnp = 0;
  double verification = 0;   // the second estimate behind the verdict: what it added beyond matching
  double total() const { return preprocessing + features + retrieval + matching + pnp + verification; }
};

struct LocalizationResult {
  // Pixels in `camera`'s grid (the undistorted full-size query), points in the world frame.
  Correspondences correspondences;
  Intrinsics camera;
  std::vector<size_t> selected;  // map image indices, best first
  QueryTimings timings;
  PnpResult pnp;
  PoseVerdict verdict;
  bool localized() const { return verdict.status == PoseStatus::kLocalized; }
};

// A method's further looks at a query whose pose the verdict did not accept, each given that pose
// and appending correspondences to the result. Empty for a method without them.
struct PoseGuidedLooks {
  using Look = std::function<void(const Pose& pose, LocalizationResult& result)>;
  // The mapping images that pose sees (added to `selected`). Its answer replaces the first
  // whenever PnP finds a pose.
  Look more_images;
  // Pairs that pose places close to their query keypoint, among matches a looser test lets
  // through. Chosen by the pose, they agree with it by construction, so their answer is taken
  // only when `localized`.
  Look nearby_pairs;
};

// The queries' side of a map, whatever the method. `localize` checks the options and the
// query's intrinsics against the image (InputError naming the field), runs the method, then
// PnP-RANSAC and the verdict. It may be called from several threads at once; the thread pools
// they share are set before (setTorchThreadCount), or held by a ThreadCountLease on each.
class Localizer {
 public:
  virtual ~Localizer() = default;
  virtual LocalizationMethod method() const = 0;
  virtual std::string modelId() const { return ""; }  // empty for methods without a network
  virtual bool metric() const = 0;
  virtual const std::vector<MapCamera>& cameras() const = 0;
  // How much larger this method's errors run than its inliers predict: the evidence's predicted
  // uncertainties are the inliers' covariance times this (scalePredictedUncertainty).
  virtual double uncertaintyScale() const { return 1.0; }
  // Which pairs the evidence's intrinsics fits use (measureEvidence).
  virtual IntrinsicsFitPairs intrinsicsFitPairs() const { return IntrinsicsFitPairs::kExplained; }
  // At most `max_points` of the map's world points, taken evenly over the map (what the server's
  // viewer draws); none for a method whose map holds no points.
  virtual std::vector<Eigen::Vector3d> mapPoints(size_t /*max_points*/) const { return {}; }

  LocalizationResult localize(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                              const LocalizeOptions& options) const;

 protected:
  // Fills the correspondences, camera, selection and timings. `second_estimate` receives the
  // method's own second estimate for the verdict's agreement test; left empty, a half-sample
  // estimate (halfSampleEstimate) stands in. `pose_guided` may receive the method's further looks,
  // which localize() takes in turn while the pose is not `localized` (LocalizeOptions::
  // pose_guided_retrieval); they must stay valid until localize() returns.
  virtual void predict(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                       const LocalizeOptions& options, LocalizationResult& result,
                       std::optional<PnpResult>& second_estimate, PoseGuidedLooks& pose_guided) const = 0;

 private:
  // One of `pose_guided`'s looks at a result not `localized`: its answer replaces the result when
  // PnP finds a pose and, if `only_if_localized`, the verdict accepts it.
  void lookAgain(const PoseGuidedLooks::Look& look, bool only_if_localized, const LocalizeOptions& options,
                 LocalizationResult& result) const;
  // PnP on the result's correspondences, then the evidence (with `second`, else a half-sample
  // estimate) and the verdict. Adds to the result's PnP and verification times.
  void estimateAndJudge(LocalizationResult& result, std::optional<PnpResult> second,
                        const LocalizeOptions& options) const;
};

// Localizes one made-up query (noise, at the first mapping camera's size and intrinsics) and
// forgets it, so that a server's first client does not pay for what every later query reuses:
// OpenCV's SIFT buffers (a first classical query took 274-316 ms on redkitchen, the next 85-125
// ms) and FastForward's token-VLAD image descriptors (0.1 s; a map written before 5 Dec 2026 also
// learns its vocabulary then, 1.3-1.5 s). Best effort: returns what it did for a log line
// ("warmed up by a made-up query in 0.2 s"), or, where the first camera is one no query could
// have (an edited map's focal length of 1e6 px), why it did not; the map still answers queries
// that bring their own intrinsics.
std::string warmUp(const Localizer& localizer, const LocalizeOptions& options);

}  // namespace ffloc
