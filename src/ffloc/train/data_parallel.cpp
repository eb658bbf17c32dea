#include "ffloc/train/data_parallel.h"

#include <cstring>
#include <thread>

#include <ATen/ops/cat.h>
#include <ATen/ops/full.h>
#include <ATen/ops/zeros.h>
#include <ATen/ops/zeros_like.h>
#ifdef FFLOC_WITH_GLOO
#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#endif
#include <torch/csrc/distributed/c10d/TCPStore.hpp>
#ifdef FFLOC_WITH_NCCL
#include <torch/csrc/distributed/c10d/ProcessGroupNCCL.hpp>
#endif

#include <chrono>
#include <cstdlib>
#include <functional>
#include <stdexcept>

#include "ffloc/core/error.h"
#include "ffloc/core/host_address.h"

namespace ffloc {

namespace {

int integerVariable(const char* name, int fallback, int minimum, int maximum) {
  const char* text = std::getenv(name);
  if (!text || !*text) return fallback;
  char* end = nullptr;
  const long value = std::strtol(text, &end, 10);
  if (*end != '\0' || value < minimum || value > maximum) {
    throwInputError("environment variable " + std::string(name), 0,
                    "'" + std::string(text) + "' is not a whole number in [" + std::to_string(minimum) + ", " +
                        std::to_string(maximum) + "]");
  }
  return static_cast<int>(value);
}

#ifdef FFLOC_WITH_GLOO
// Gloo binds to the interface torch's launcher would use: GLOO_SOCKET_IFNAME when set, loopback
// for a run on one machine, else the address this host's name resolves to.
std::shared_ptr<::gloo::transport::Device> glooDevice(const DistributedEnvironment& environment) {
  if (const char* interface = std::getenv("GLOO_SOCKET_IFNAME"); interface && *interface) {
    return c10d::ProcessGroupGloo::createDeviceForInterface(interface);
  }
  if (isLoopbackHost(environment.master_addr)) return c10d::ProcessGroupGloo::createDeviceForHostname("127.0.0.1");
  return c10d::ProcessGroupGloo::createDefaultDevice();
}
#endif

}  // namespace

DistributedEnvironment DistributedEnvironment::fromProcessEnvironment() {
  DistributedEnvironment environment;
  environment.world_size = integerVariable("WORLD_SIZE", 1, 1, 1 << 20);
  environment.rank = integerVariable("RANK", 0, 0, environment.world_size - 1);
  environment.local_world_size = integerVariable("LOCAL_WORLD_SIZE", 1, 1, environment.world_size);
  environment.local_rank = integerVariable("LOCAL_RANK", 0, 0, environment.local_world_size - 1);
  environment.master_port = integerVariable("MASTER_PORT", environment.master_port, 1, 65535);
  if (const char* address = std::getenv("MASTER_ADDR"); address && *address) environment.master_addr = address;
  return environment;
}

namespace {

// c10d's messages carry their C++ backtrace after the first line.
std::string firstLineOf(const std::exception& error) {
  const std::string what = error.what();
  return what.substr(0, what.find('\n'));
}

// A rank that stopped or crashed fails the others' next collective inside gloo or NCCL, whose
// message ("[./gloo/transport/tcp/pair.cc:598] Connection closed by peer") was reported as an
// internal error.
void runCollective(int64_t rank, const char* collective, const std::function<void()>& run) {
  try {
    run();
  } catch (const std::exception& e) {
    throwInputError("rank " + std::to_string(rank), 0,
                    std::string(collective) + " failed: another rank stopped or lost its connection (its own output "
                    "says why), or the collective timeout passed: " + firstLineOf(e));
  }
}

}  // namespace

// The collectives of whichever c10d process group the run uses; in libtorch 1.x that is a
// ProcessGroup, in 2.x a Backend, so only the calls every version shares are kept.
struct DataParallel::Backend {
  c10::intrusive_ptr<c10d::Store> store;
  std::function<void(std::vector<at::Tensor>&)> all_reduce_sum;
  std::function<void(std::vector<at::Tensor>&)> broadcast;
  std::function<void()> barrier;

  // `timeout`: each collective's, which may differ from the group's own (its rendezvous).
  template <typename Group>
  void bind(const c10::intrusive_ptr<Group>& group, std::chrono::milliseconds timeout, int64_t rank) {
    all_reduce_sum = [group, timeout, rank](std::vector<at::Tensor>& tensors) {
      c10d::AllreduceOptions options;
      options.reduceOp = c10d::ReduceOp::SUM;
      options.timeout = timeout;
      runCollective(rank, "all-reduce", [&] { group->allreduce(tensors, options)->wait(); });
    };
    broadcast = [group, timeout, rank](std::vector<at::Tensor>& tensors) {
      c10d::BroadcastOptions options;
      options.rootRank = 0;
      options.timeout = timeout;
      runCollective(rank, "broadcast", [&] { group->broadcast(tensors, options)->wait(); });
    };
    barrier = [group, timeout, rank] {
      c10d::BarrierOptions options;
      options.timeout = timeout;
      runCollective(rank, "barrier", [&] { group->barrier(options)->wait(); });
    };
  }
};

DataParallel::DataParallel(const DistributedEnvironment& environment, bool cuda, double rendezvous_timeout_s,
                           double collective_timeout_s)
    : environment_(environment), cuda_(cuda), backend_(std::make_unique<Backend>()) {
  const auto timeout = std::chrono::milliseconds(static_cast<int64_t>(collective_timeout_s * 1000));
  c10d::TCPStoreOptions store_options;
  store_options.port = static_cast<uint16_t>(environment.master_port);
  store_options.isServer = environment.rank == 0;
  store_options.numWorkers = static_cast<size_t>(environment.world_size);
  store_options.waitWorkers = true;
  // A rank that never starts, or another MASTER_PORT, left the others waiting an hour in silence.
  const auto rendezvous = std::chrono::milliseconds(static_cast<int64_t>(rendezvous_timeout_s * 1000));
  store_options.timeout = rendezvous;
  const auto cannotJoin = [&](const std::string& why) {
    throwInputError("rendezvous at " + environment.master_addr + ":" + std::to_string(environment.master_port), 0,
                    "rank " + std::to_string(environment.rank) + " of " + std::to_string(environment.world_size) + why +
                        " (did every rank start, with the same MASTER_ADDR and MASTER_PORT?)");
  };
  // A name that resolves to nothing was reported as the rendezvous timing out, after the timeout.
  if (const std::string problem = hostResolutionProblem(environment.master_addr); !problem.empty())
    throwInputError("MASTER_ADDR", 0, "'" + environment.master_addr + "' does not resolve: " + problem);
  try {
    backend_->store = c10::make_intrusive<c10d::TCPStore>(environment.master_addr, store_options);
    // Every rank counts itself in and waits for the others here, within the rendezvous timeout:
    // the process group's own joining waits as long as its collectives may (an hour).
    // A second process given the same RANK joined, passed the count below and waited for ever
    // in the process group's connections.
    if (backend_->store->add("ffloc/rank/" + std::to_string(environment.rank), 1) > 1)
      cannotJoin(": another process has already joined as this rank (two processes were given RANK=" +
                 std::to_string(environment.rank) + ")");
    const std::string joined_key = "ffloc/joined";
    int64_t joined = backend_->store->add(joined_key, 1);
    const auto deadline = std::chrono::steady_clock::now() + rendezvous;
    while (joined < environment.world_size) {
      if (std::chrono::steady_clock::now() > deadline)
        cannotJoin(": only " + std::to_string(joined) + " of " + std::to_string(environment.world_size) +
                   " ranks joined within " + std::to_string(static_cast<int64_t>(rendezvous_timeout_s)) + " s");
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      joined = backend_->store->add(joined_key, 0);
    }
    backend_->store->setTimeout(timeout);
    if (cuda) {
#ifdef FFLOC_WITH_NCCL
      auto options = c10d::ProcessGroupNCCL::Options::create();
      options->timeout = timeout;
      backend_->bind(
          c10::make_intrusive<c10d::ProcessGroupNCCL>(backend_->store, environment.rank, environment.world_size, options),
          timeout, environment.rank);
#else
      throw InputError("device 'cuda': this build's libtorch has no NCCL; train on cpu or rebuild against a CUDA libtorch");
#endif
    } else {
#ifdef FFLOC_WITH_GLOO
      // libtorch 1.13's gloo collectives take the group's timeout, not their options'.
      auto options = c10d::ProcessGroupGloo::Options::create(timeout);
      options->devices.push_back(glooDevice(environment));
      backend_->bind(
          c10::make_intrusive<c10d::ProcessGroupGloo>(backend_->store, environment.rank, environment.world_size, options),
          timeout, environment.rank);
#else
      throw InputError("device 'cpu': this build found no gloo headers beside its libtorch (PyTorch's pip wheels ship "
                       "none), so several CPU ranks cannot train together; train on cuda, or build against a libtorch "
                       "with them (Debian's libtorch-dev)");
#endif
    }
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    cannotJoin(" could not join: " + firstLineOf(e));
  }
}

DataParallel::~DataParallel() = default;

void DataParallel::allReduceSum(const std::vector<at::Tensor>& tensors, int64_t bucket_bytes) {
  size_t begin = 0;
  while (begin < tensors.size()) {
    size_t end = begin;
    int64_t bytes = 0;
    std::vector<at::Tensor> flat;
    while (end < tensors.size() && (end == begin || bytes + static_cast<int64_t>(tensors[end].nbytes()) <= bucket_bytes)) {
      bytes += static_cast<int64_t>(tensors[end].nbytes());
      flat.push_back(tensors[end].reshape({-1}));
      ++end;
    }
    std::vector<at::Tensor> bucket = {at::cat(flat)};
    backend_->all_reduce_sum(bucket);
    int64_t offset = 0;
    for (size_t i = begin; i < end; ++i) {
      const int64_t count = tensors[i].numel();
      tensors[i].copy_(bucket[0].narrow(0, offset, count).view(tensors[i].sizes()));
      offset += count;
    }
    begin = end;
  }
}

void DataParallel::broadcastFromRankZero(const std::vector<at::Tensor>& tensors) {
  for (const at::Tensor& tensor : tensors) {
    std::vector<at::Tensor> one = {tensor};
    backend_->broadcast(one);
  }
}

void DataParallel::barrier() { backend_->barrier(); }

at::Tensor DataParallel::onDevice(const at::Tensor& tensor) const {
  // This rank's GPU: NCCL refuses two ranks of one machine on one device.
  return cuda_ ? tensor.to(at::Device(at::kCUDA, static_cast<c10::DeviceIndex>(environment_.local_rank))) : tensor;
}

std::string DataParallel::broadcastTextFromRankZero(const std::string& text) {
  std::vector<at::Tensor> length = {onDevice(at::full({1}, static_cast<int64_t>(text.size()), at::kLong))};
  backend_->broadcast(length);
  const int64_t size = length[0].cpu().item<int64_t>();
  at::Tensor bytes = at::zeros({size}, at::kByte);
  if (environment_.rank == 0) std::memcpy(bytes.data_ptr(), text.data(), text.size());
  std::vector<at::Tensor> shared = {onDevice(bytes)};
  backend_->broadcast(shared);
  const at::Tensor received = shared[0].cpu().contiguous();
  return std::string(static_cast<const char*>(received.data_ptr()), static_cast<size_t>(size));
}

bool DataParallel::anyRank(bool flag) {
  std::vector<at::Tensor> count = {onDevice(at::full({1}, flag ? 1.0f : 0.0f, at::kFloat))};
  backend_->all_reduce_sum(count);
  return count[0].cpu().item<float>() > 0;
}

std::vector<at::Tensor> gradientsOf(const std::vector<std::pair<std::string, at::Tensor>>& parameters) {
  std::vector<at::Tensor> gradients;
  for (const auto& entry : parameters) {
    at::Tensor parameter = entry.second;
    if (!parameter.grad().defined()) parameter.mutable_grad() = at::zeros_like(parameter);
    gradients.push_back(parameter.grad());
  }
  return gradients;
}

}  // namespace ffloc
