// The sharded rollouts of sysid/mpi/sharded_rollout.h.
#include "sysid/mpi/sharded_rollout.h"

#include <mpi.h>

#include <string>

#include "sysid/mpi/distributed_fit.h"

namespace mjsysid::mpi {

void ShardedRollout(Simulator& sim, const std::vector<SequenceInput>& inputs,
                    std::vector<Trajectory>* out) {
  const int size = Size(), rank = Rank(), S = static_cast<int>(inputs.size());
  const int first = static_cast<int>(static_cast<long long>(rank) * S / size);
  const int last = static_cast<int>(static_cast<long long>(rank + 1) * S / size);
  // this rank's share, its failure agreed by every rank
  std::vector<Trajectory> mine;
  std::string error;
  try {
    sim.Rollout(std::vector<SequenceInput>(inputs.begin() + first, inputs.begin() + last), &mine);
  } catch (const std::exception& e) {
    error = e.what();
  }
  std::string failure;
  if (!AgreeReady(error.empty(), error, &failure)) throw SimulationError(failure, -1, -1);
  // packed: per trajectory [T, state rows, state cols, sensor rows, sensor cols, states, sensors]
  std::vector<double> send;
  for (const Trajectory& tr : mine) {
    send.insert(send.end(),
                {static_cast<double>(tr.T), static_cast<double>(tr.states.rows()),
                 static_cast<double>(tr.states.cols()), static_cast<double>(tr.sensors.rows()),
                 static_cast<double>(tr.sensors.cols())});
    send.insert(send.end(), tr.states.data(), tr.states.data() + tr.states.size());
    send.insert(send.end(), tr.sensors.data(), tr.sensors.data() + tr.sensors.size());
  }
  int count = static_cast<int>(send.size());
  std::vector<int> counts(size), displs(size, 0);
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  for (int r = 1; r < size; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<size_t>(displs[size - 1]) + counts[size - 1]);
  MPI_Allgatherv(send.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(),
                 MPI_DOUBLE, MPI_COMM_WORLD);
  // unpacked in sequence order (the ranks' shares are contiguous and in rank order)
  out->assign(S, Trajectory());
  const double* p = all.data();
  for (Trajectory& tr : *out) {
    tr.T = static_cast<int>(p[0]);
    tr.states = Eigen::Map<const RowMatrix>(p + 5, static_cast<Eigen::Index>(p[1]),
                                            static_cast<Eigen::Index>(p[2]));
    const double* sensors = p + 5 + tr.states.size();
    tr.sensors = Eigen::Map<const RowMatrix>(sensors, static_cast<Eigen::Index>(p[3]),
                                             static_cast<Eigen::Index>(p[4]));
    p = sensors + tr.sensors.size();
  }
}

}  // namespace mjsysid::mpi
