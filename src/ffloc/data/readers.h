#pragma once

#include <filesystem>
#include <string>

#include "ffloc/data/scene.h"

// One reader per dataset format. Each fills a Scene in the project conventions (camera-to-world,
// OpenCV axes and pixel convention) and throws InputError naming file and line or field on bad
// input. loadDataset (dataset.h) picks one and then applies split_mapping.txt / split_query.txt.
namespace ffloc {

// Microsoft 7-Scenes: flat frame-XXXXXX.{color.png|color.jpg,depth.png,pose.txt} (optionally in
// rgbd-frames/), or the original seq-XX/ folders with TrainSplit.txt / TestSplit.txt.
bool looksLikeSevenScenes(const std::filesystem::path& dir);
Scene readSevenScenes(const std::filesystem::path& dir);

// NeRF / instant-ngp / nerfstudio transforms.json (or transforms_{train,val,test}.json).
bool looksLikeNerf(const std::filesystem::path& dir);
Scene readNerf(const std::filesystem::path& dir);

// COLMAP text model: cameras.txt, images.txt, points3D.txt in dir, dir/sparse/0, dir/sparse,
// dir/reconstruction or dir/model; images in dir/images or beside the model.
bool looksLikeColmap(const std::filesystem::path& dir);
Scene readColmap(const std::filesystem::path& dir);

// Strecha multi-view benchmark: images/NNNN.jpg + gt_dense_cameras/NNNN.jpg.camera.
bool looksLikeStrecha(const std::filesystem::path& dir);
Scene readStrecha(const std::filesystem::path& dir);

// Cambridge Landmarks (PoseNet): dataset_train.txt / dataset_test.txt.
bool looksLikeCambridge(const std::filesystem::path& dir);
Scene readCambridge(const std::filesystem::path& dir);

// Map-free relocalization (and Wayspots in it): seq0/ (mapping), seq1/ (query), intrinsics.txt,
// poses.txt (world-to-camera quaternions), optional depth <frame>.<source>.png beside the frames.
bool looksLikeMapFree(const std::filesystem::path& dir);
Scene readMapFree(const std::filesystem::path& dir);

// The ACE / GLACE / DSAC* layout: train/ (mapping) and test/ (query) with rgb/, poses/,
// calibration/ and optional depth/, files paired by the name before the first '.'.
bool looksLikeAceLayout(const std::filesystem::path& dir);
Scene readAceLayout(const std::filesystem::path& dir);

// RIO10: seqXX_YY/ sequences of frame-NNNNNN.{color.jpg,pose.txt,rendered.depth.png}, cameras
// from the authors' intrinsics.txt ("seqXX_YY fx fy cx cy", in the folder or the one above) or
// each sequence's camera.yaml; _01 is mapping, _02 (validation) query, sequences without poses skipped.
bool looksLikeRio10(const std::filesystem::path& dir);
Scene readRio10(const std::filesystem::path& dir);

// Indoor6: images/*.{color.jpg,pose.txt,intrinsics.txt} and the splits in train_test_val.pkl
// (or, without it, a third-party converter's <scene>_{train,val,test}.txt).
bool looksLikeIndoor6(const std::filesystem::path& dir);
Scene readIndoor6(const std::filesystem::path& dir);

// kapture 1.1: sensors/ in the folder, or in mapping/ and query/.
bool looksLikeKapture(const std::filesystem::path& dir);
Scene readKapture(const std::filesystem::path& dir);

// Frame::name for an image: its path relative to the scene root, with forward slashes.
std::string frameName(const std::filesystem::path& image_path, const std::filesystem::path& root);

// A scene with no frames yet: root = dir, name = dir's last component.
Scene emptyScene(const std::filesystem::path& dir, const std::string& format, bool metric);

}  // namespace ffloc
