// probekit bake across processes (docs/baking.md#distributed-bakes): under `mpirun` or `srun` each
// process runs the same bake and the probes are shared out through MPI (baker::ProbeDistributor).
// Built only when CMake finds MPI (PROBEKIT_WITH_MPI); without it every process bakes alone.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "probekit/baker/bake.hpp"

namespace probekit::cli {

// Traffic of a distributed bake, counted by the process that sends it.
struct DistributedTraffic {
    uint64_t chunks = 0;         // chunks handed out by rank 0 (its own included)
    uint64_t resultBytes = 0;    // results the other ranks sent to rank 0
    uint64_t broadcastBytes = 0; // results rank 0 sent back (every batch, to every other rank)
    uint64_t controlBytes = 0;   // requests and chunk assignments
    uint64_t probes = 0;         // probes in the batches
};

class DistributedBake {
public:
    // Joins the job when this process was started by an MPI launcher (the environment says so:
    // OMPI_COMM_WORLD_SIZE, PMIX_RANK or PMI_RANK); otherwise, or without MPI support in this
    // build, a job of one process. Call once, before any thread starts; ends with the object.
    static std::unique_ptr<DistributedBake> join(int& argc, char**& argv);
    virtual ~DistributedBake() = default;

    virtual int rank() const = 0;
    virtual int size() const = 0;
    // The distributor for BakeOptions (null for a job of one process).
    virtual baker::ProbeDistributor* distributor() = 0;
    virtual DistributedTraffic traffic() const = 0;
    // Ends the whole job with an error message (rank 0 or not): a process that fails alone
    // must not leave the others waiting for it.
    [[noreturn]] virtual void abort(const std::string& message) = 0;
};

// The process's job, set by main() before the command runs.
DistributedBake* currentJob();
void setCurrentJob(DistributedBake* job);

} // namespace probekit::cli
