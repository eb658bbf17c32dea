#pragma once

#include <ATen/core/Tensor.h>

#include <Eigen/Core>
#include <vector>

#include "ffloc/classical/vlad.h"
#include "ffloc/io/map_file.h"

namespace ffloc {

// VLAD over the encoder's own tokens as local descriptors, with a vocabulary learned from the
// map's tokens when the map is built (MapFile::token_vocabulary). Each image's descriptor is
// words x token width floats (128 KB for the dense-SIFT encoder's 256-wide tokens), computed
// from its stored tokens rather than stored. For the dense-SIFT encoder this is DenseVLAD (Torii
// et al. 2015: dense RootSIFT at two scales), which ranked the pose-nearest mapping image better
// than pooling the same tokens on the held-out synthetic scenes (docs/pipeline.md, "Retrieval").
class TokenVlad {
 public:
  // kWords = 128: recall@10 of the pose-nearest image on the 10 held-out synthetic scenes (150
  // queries, the dense-SIFT encoder) was 0.47 / 0.50 / 0.51 / 0.55 / 0.53 with 16 / 32 / 64 / 128
  // / 256 words.
  static constexpr int kWords = 128;

  // The map's stored vocabulary, or one learnt from its tokens where it stores none (a map
  // written before it was stored: 1.5 s for redkitchen's 150 images on a 2-vCPU AMD EPYC).
  explicit TokenVlad(const MapFile& map);
  // kWords words learnt from the map's tokens, words x token_dim row-major.
  static std::vector<float> learnVocabulary(const MapFile& map);

  // One unit-norm descriptor per map image, in map order.
  const std::vector<Eigen::VectorXf>& imageDescriptors() const { return images_; }
  // The descriptor of one image's tokens, (T, D) or (1, T, D) of any float type.
  Eigen::VectorXf describe(const at::Tensor& tokens) const;

 private:
  VladVocabulary vocabulary_;
  std::vector<Eigen::VectorXf> images_;
};

}  // namespace ffloc
