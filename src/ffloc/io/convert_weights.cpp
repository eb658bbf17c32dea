#include "ffloc/io/convert_weights.h"

#include <algorithm>
#include <deque>
#include <map>
#include <tuple>
#include <utility>

#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/threads.h"
#include "ffloc/io/half.h"
#include "ffloc/io/tensor_checksums.h"

namespace ffloc {

DType parseFloatDType(const std::string& text, const std::string& field) {
  std::string upper = text;
  std::transform(upper.begin(), upper.end(), upper.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  const std::optional<DType> dtype = dtypeFromString(upper);
  if (!dtype || !isFloatingPoint(*dtype)) {
    throw InputError(field + ": unknown floating-point dtype '" + text + "' (f32, f16, bf16, f64)");
  }
  return *dtype;
}

ConvertWeightsSummary convertWeights(const std::filesystem::path& input,
                                     const std::filesystem::path& output,
                                     const ConvertWeightsOptions& options) {
  if (options.float_dtype && !isFloatingPoint(*options.float_dtype)) {
    throw InputError(std::string("convert: target dtype ") + toString(*options.float_dtype) +
                     " is not a floating-point type");
  }
  // Written over its input, an f32 original became its f16 copy: the only full-precision weights lost.
  std::error_code ignored;
  if (std::filesystem::equivalent(input, output, ignored))
    throwInputError(output.string(), 0, "output: is the input file; write the converted weights to another path");
  // A folder failed only at the final rename, after the whole conversion.
  if (std::filesystem::is_directory(output, ignored))
    throwInputError(output.string(), 0, "output: is a folder; name the safetensors file to write");
  const std::unique_ptr<TensorArchive> archive = openTensorArchive(input);
  // Converted unchecked, a damaged checkpoint would come out as a file with nothing to check.
  verifyChecksums(*archive, resolveThreadCount(0));
  // A safetensors file of metadata alone converted to another such file with exit 0; the .pth
  // reader already refused a checkpoint without tensors.
  if (archive->names().empty()) throwInputError(input.string(), 0, "holds no tensor; nothing to convert");
  ConvertWeightsSummary summary;
  summary.tensors_read = archive->names().size();

  // Exact aliases are the same bytes seen under several names; what differs only in part (two
  // views of one storage) is written as separate copies.
  std::vector<std::string> names = archive->names();
  std::sort(names.begin(), names.end());
  using Identity = std::tuple<const uint8_t*, size_t, DType, std::vector<int64_t>>;
  std::map<Identity, std::string> kept;
  std::vector<TensorView> views;
  for (const std::string& name : names) {
    const TensorView& view = archive->at(name);
    const auto [slot, inserted] = kept.emplace(Identity{view.data, view.nbytes, view.dtype, view.shape}, name);
    // Empty tensors have no bytes to share, so each keeps its name.
    if (!inserted && view.nbytes > 0) {
      ++summary.aliases_dropped;
      continue;
    }
    views.push_back(view);
  }

  std::deque<std::vector<uint8_t>> casts;
  if (options.float_dtype) {
    for (TensorView& view : views) {
      if (!isFloatingPoint(view.dtype) || view.dtype == *options.float_dtype) continue;
      std::vector<uint8_t> cast;
      try {
        cast = castFloatTensor(view, *options.float_dtype);
      } catch (const InputError& e) {
        throwInputError(input.string(), 0, e.what());  // the tensor's error named no file
      }
      const std::vector<uint8_t>& bytes = casts.emplace_back(std::move(cast));
      view.dtype = *options.float_dtype;
      view.data = bytes.data();
      view.nbytes = bytes.size();
    }
  }

  std::map<std::string, std::string> metadata = archive->metadata();
  metadata.emplace("format", "pt");
  metadata["source"] = input.filename().string();
  // The input's checksums are of its own tensors and metadata, which casts and aliases change.
  if (metadata.count(kChecksumsMetadataKey)) metadata = withChecksums(views, metadata);

  ProgressBar progress("convert " + input.filename().string(), views.size(), options.quiet);
  writeSafetensors(output, views, metadata, [&](size_t written) { progress.update(written); });
  progress.finish();
  summary.tensors_written = views.size();
  for (const TensorView& view : views) summary.bytes_written += view.nbytes;
  return summary;
}

}  // namespace ffloc
