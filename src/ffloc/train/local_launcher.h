#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ffloc {

// What is wrong with starting `ranks` ranks on this machine, or empty: at most one per hardware
// thread, since a rank computes on at least one core (1000 ranks forked about 100 processes on
// 2 cores, none of which got anywhere).
std::string localRanksProblem(int64_t ranks);

// Starts `arguments` (arguments[0] is the program) as `ranks` processes of one data-parallel run
// on this machine, as `torchrun --nproc-per-node` does: each gets RANK = LOCAL_RANK = its index,
// WORLD_SIZE = LOCAL_WORLD_SIZE = ranks, and MASTER_ADDR / MASTER_PORT (loopback and a free port
// unless already set). Waits for all; when one fails the others are stopped. Returns 0 when all
// succeeded, else the first failure's exit status (128 + signal for a killed rank). InputError
// "ranks: <localRanksProblem>" before starting any.
int runLocalRanks(const std::vector<std::string>& arguments, int ranks);

// A TCP port on 127.0.0.1 that is free now (for MASTER_PORT); another process may take it before
// it is bound.
int freeLoopbackPort();

}  // namespace ffloc
