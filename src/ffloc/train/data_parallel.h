#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace ffloc {

// Where this process stands in a data-parallel run, as torchrun, SLURM wrappers and Kubernetes
// operators describe it: RANK, WORLD_SIZE, LOCAL_RANK, LOCAL_WORLD_SIZE, MASTER_ADDR, MASTER_PORT.
struct DistributedEnvironment {
  int rank = 0;
  int world_size = 1;
  int local_rank = 0;
  int local_world_size = 1;
  std::string master_addr = "127.0.0.1";
  int master_port = 29500;

  bool distributed() const { return world_size > 1; }
  // InputError naming the variable for a value that is not a number or out of range. Without
  // WORLD_SIZE the process is a run of its own (rank 0 of 1).
  static DistributedEnvironment fromProcessEnvironment();
};

// Gradient averaging across the ranks of a run through PyTorch's c10d: a TCPStore on MASTER_ADDR
// for the rendezvous, ProcessGroupGloo on CPU, ProcessGroupNCCL on CUDA where libtorch has it.
// Every rank must make the same calls in the same order.
class DataParallel {
 public:
  // Blocks until all world_size ranks have joined (InputError after `rendezvous_timeout_s`); a
  // collective then waits for the other ranks up to `collective_timeout_s` (rank 0 validating or
  // writing a checkpoint keeps the others waiting that long).
  DataParallel(const DistributedEnvironment& environment, bool cuda, double rendezvous_timeout_s = 1800,
               double collective_timeout_s = 3600);
  ~DataParallel();
  DataParallel(const DataParallel&) = delete;
  DataParallel& operator=(const DataParallel&) = delete;

  const DistributedEnvironment& environment() const { return environment_; }

  // Sums the tensors over the ranks, in place, in buckets of at most `bucket_bytes` so that one
  // collective carries many small gradients. Every rank must pass tensors of the same shapes.
  void allReduceSum(const std::vector<at::Tensor>& tensors, int64_t bucket_bytes = 25 << 20);
  // Rank 0's values everywhere, in place.
  void broadcastFromRankZero(const std::vector<at::Tensor>& tensors);
  void barrier();
  // Rank 0's `text` on every rank.
  std::string broadcastTextFromRankZero(const std::string& text);
  // Whether `flag` is true on any rank.
  bool anyRank(bool flag);

 private:
  struct Backend;
  at::Tensor onDevice(const at::Tensor& tensor) const;

  DistributedEnvironment environment_;
  bool cuda_;
  std::unique_ptr<Backend> backend_;
};

// The gradients of `parameters` (zeros where a parameter has none yet), as allReduceSum wants them.
std::vector<at::Tensor> gradientsOf(const std::vector<std::pair<std::string, at::Tensor>>& parameters);

}  // namespace ffloc
