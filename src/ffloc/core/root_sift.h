#pragma once

#include <opencv2/core.hpp>

namespace ffloc {

// RootSIFT (Arandjelovic & Zisserman 2012) in place on CV_32F rows: L1-normalise, then square-root,
// so that Euclidean distance and dot products compare descriptors like the Hellinger kernel, which
// matches better than raw SIFT. Rows become unit L2 norm (all-zero rows stay zero).
void toRootSift(cv::Mat& descriptors);

}  // namespace ffloc
