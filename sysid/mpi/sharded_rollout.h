// `mpirun -n N sysid simulate`: the rollouts of a batch sharded across the MPI ranks.
//
// Every rank calls ShardedRollout with the same inputs (S sequences, generated from the same
// experiment and seeds); rank r simulates its contiguous share [r S / N, (r + 1) S / N) with its
// own threads, then every rank receives every trajectory (MPI_Allgatherv): T, states
// ((T + 1) x nphys) and sensors (T x nsensordata), row-major as Trajectory holds them (`full`,
// `ncon` and `solver` stay empty). A rollout is the same bits whichever rank runs it, so the log
// equals that of one process. Failure: a rollout that throws on any rank (SimulationError,
// MujocoError) throws SimulationError on every rank with the first failing rank's message
// ("rank R on host H: ..."), so no rank waits for another.
#pragma once

#include <vector>

#include "core/simulator.h"

namespace mjsysid::mpi {

void ShardedRollout(Simulator& sim, const std::vector<SequenceInput>& inputs,
                    std::vector<Trajectory>* out);

}  // namespace mjsysid::mpi
