#include "distributed.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>

#ifdef PROBEKIT_WITH_MPI
#include <algorithm>
#include <atomic>
#include <chrono>
#include <system_error>
#include <thread>
#include <vector>

// The C API only: without these, mpi.h in C++ pulls in the removed C++ bindings, whose library
// MPI::MPI_C does not link.
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

namespace probekit::cli {
namespace {

DistributedBake* g_job = nullptr;

// Whether an MPI launcher started this process: Open MPI's mpirun, or a PMIx or PMI launcher
// such as Slurm's srun (a plain process inside a Slurm allocation is not one).
bool launchedByMpi(int* size) {
    for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}) {
        if (const char* value = std::getenv(name)) {
            *size = std::atoi(value);
            return true;
        }
    }
    for (const char* name : {"PMIX_RANK", "PMI_RANK"}) {
        if (std::getenv(name)) {
            *size = 0; // unknown until MPI says
            return true;
        }
    }
    return false;
}

// A job of one process.
class SingleProcess final : public DistributedBake {
public:
    int rank() const override { return 0; }
    int size() const override { return 1; }
    baker::ProbeDistributor* distributor() override { return nullptr; }
    DistributedTraffic traffic() const override { return {}; }
    [[noreturn]] void abort(const std::string& message) override {
        std::fprintf(stderr, "%s\n", message.c_str());
        std::exit(1);
    }
};

#ifdef PROBEKIT_WITH_MPI

constexpr int kTagResult = 1; // worker -> rank 0: a chunk's results (or none, to ask for work)
constexpr int kTagAssign = 2; // rank 0 -> worker: the next chunk, or none (the batch is done)

// A chunk's results as sent: this header, then the SH (27 floats a probe), then the validity
// bytes. begin == end: no results (the first request of a batch).
struct ResultHeader {
    uint64_t begin;
    uint64_t end;
    baker::ProbeChunkStats stats;
};
struct Assignment {
    int64_t begin; // -1: no more chunks in this batch
    int64_t end;
};

// How long a waiting process sleeps between polls: Open MPI's blocking calls spin on a core,
// which on a node shared with the bake's own threads would take it from them.
constexpr auto kPoll = std::chrono::microseconds(200);

void waitFor(MPI_Request& request) {
    int done = 0;
    while (true) {
        MPI_Test(&request, &done, MPI_STATUS_IGNORE);
        if (done) {
            return;
        }
        std::this_thread::sleep_for(kPoll);
    }
}

// Rank 0's bytes to every rank, in pieces whose count fits MPI's int (a batch of 20 million
// probes is 2 GiB of SH).
void broadcast(void* data, size_t bytes) {
    constexpr size_t kPiece = size_t(1) << 30;
    for (size_t offset = 0; offset < bytes; offset += kPiece) {
        MPI_Request request;
        MPI_Ibcast(static_cast<char*>(data) + offset, int(std::min(kPiece, bytes - offset)),
                   MPI_BYTE, 0, MPI_COMM_WORLD, &request);
        waitFor(request);
    }
}

class MpiJob final : public DistributedBake, public baker::ProbeDistributor {
public:
    MpiJob(int rank, int size) : m_rank(rank), m_size(size) {}
    ~MpiJob() override { MPI_Finalize(); }

    int rank() const override { return m_rank; }
    int size() const override { return m_size; }
    baker::ProbeDistributor* distributor() override { return m_size > 1 ? this : nullptr; }
    DistributedTraffic traffic() const override { return m_traffic; }
    [[noreturn]] void abort(const std::string& message) override {
        std::fprintf(stderr, "rank %d of %d: %s\n", m_rank, m_size, message.c_str());
        std::fflush(stderr);
        MPI_Abort(MPI_COMM_WORLD, 1);
        std::exit(1); // MPI_Abort does not return
    }

    baker::ProbeChunkStats run(size_t count, std::span<sh::ShRgb> sh, std::span<uint8_t> valid,
                               const Compute& compute) override {
        // Chunks small enough that every rank gets many (probes cost very different amounts:
        // inside walls, near lights), large enough that a message carries real work.
        const size_t chunk = std::clamp<size_t>(count / (size_t(m_size) * 16), 1, 256);
        baker::ProbeChunkStats total =
            m_rank == 0 ? coordinate(count, chunk, sh, valid, compute) : work(sh, valid, compute);
        // Every rank continues with every result (dilation, visibility, the next bricked
        // level all read them), so rank 0 broadcasts the batch.
        broadcast(sh.data(), sh.size() * sizeof(sh::ShRgb));
        broadcast(valid.data(), valid.size());
        broadcast(&total, sizeof total);
        if (m_rank == 0) {
            m_traffic.broadcastBytes += uint64_t(m_size - 1) * (sh.size() * sizeof(sh::ShRgb) +
                                                                valid.size() + sizeof total);
            m_traffic.probes += count;
        }
        return total;
    }

private:
    // Rank 0: a thread hands chunks to the other ranks as they ask and stores their results,
    // while this thread bakes chunks from the same counter. Only that thread calls MPI until it
    // is joined (MPI_THREAD_SERIALIZED). When the system refuses that thread, this thread bakes
    // every chunk and then serves the other ranks, who are told there is nothing left: the
    // same results, computed on one rank.
    baker::ProbeChunkStats coordinate(size_t count, size_t chunk, std::span<sh::ShRgb> sh,
                                      std::span<uint8_t> valid, const Compute& compute) {
        const size_t chunks = (count + chunk - 1) / chunk;
        std::atomic<size_t> next{0};
        baker::ProbeChunkStats remote;
        const auto serve = [&] {
            int active = m_size - 1;
            std::vector<char> buffer;
            while (active > 0) {
                int flag = 0;
                MPI_Status status;
                MPI_Iprobe(MPI_ANY_SOURCE, kTagResult, MPI_COMM_WORLD, &flag, &status);
                if (!flag) {
                    std::this_thread::sleep_for(kPoll);
                    continue;
                }
                int bytes = 0;
                MPI_Get_count(&status, MPI_BYTE, &bytes);
                buffer.resize(size_t(bytes));
                MPI_Recv(buffer.data(), bytes, MPI_BYTE, status.MPI_SOURCE, kTagResult,
                         MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                ResultHeader header;
                std::memcpy(&header, buffer.data(), sizeof header);
                const size_t n = size_t(header.end - header.begin);
                if (n > 0) {
                    std::memcpy(static_cast<void*>(sh.data() + header.begin),
                                buffer.data() + sizeof header, n * sizeof(sh::ShRgb));
                    std::memcpy(valid.data() + header.begin,
                                buffer.data() + sizeof header + n * sizeof(sh::ShRgb), n);
                    remote += header.stats;
                    m_traffic.resultBytes += uint64_t(bytes);
                } else {
                    m_traffic.controlBytes += uint64_t(bytes);
                }
                const size_t i = next.fetch_add(1);
                Assignment a{-1, -1};
                if (i < chunks) {
                    a = {int64_t(i * chunk), int64_t(std::min(count, (i + 1) * chunk))};
                    ++m_traffic.chunks;
                } else {
                    --active;
                }
                MPI_Send(&a, int(sizeof a), MPI_BYTE, status.MPI_SOURCE, kTagAssign,
                         MPI_COMM_WORLD);
                m_traffic.controlBytes += sizeof a;
            }
        };
        std::thread coordinator;
        try {
            coordinator = std::thread(serve);
        } catch (const std::system_error&) {
            // No coordinator: the loop below takes every chunk, serve() then runs here.
        }
        baker::ProbeChunkStats local;
        uint64_t local_chunks = 0; // the coordinator counts the others' in m_traffic
        for (size_t i = next.fetch_add(1); i < chunks; i = next.fetch_add(1)) {
            local += compute(i * chunk, std::min(count, (i + 1) * chunk));
            ++local_chunks;
        }
        if (coordinator.joinable()) {
            coordinator.join();
        } else {
            serve();
        }
        m_traffic.chunks += local_chunks;
        local += remote;
        return local;
    }

    // Another rank: ask, bake, send back, until rank 0 says the batch is done.
    baker::ProbeChunkStats work(std::span<sh::ShRgb> sh, std::span<uint8_t> valid,
                                const Compute& compute) {
        std::vector<char> message(sizeof(ResultHeader));
        ResultHeader header{0, 0, {}};
        while (true) {
            std::memcpy(message.data(), &header, sizeof header);
            MPI_Request send;
            MPI_Isend(message.data(), int(message.size()), MPI_BYTE, 0, kTagResult, MPI_COMM_WORLD,
                      &send);
            waitFor(send);
            Assignment a;
            MPI_Request receive;
            MPI_Irecv(&a, int(sizeof a), MPI_BYTE, 0, kTagAssign, MPI_COMM_WORLD, &receive);
            waitFor(receive);
            if (a.begin < 0) {
                return {}; // the batch's totals come with rank 0's broadcast
            }
            const auto begin = size_t(a.begin);
            const auto end = size_t(a.end);
            header = ResultHeader{begin, end, compute(begin, end)};
            const size_t n = end - begin;
            message.resize(sizeof header + n * sizeof(sh::ShRgb) + n);
            std::memcpy(message.data() + sizeof header, static_cast<const void*>(sh.data() + begin),
                        n * sizeof(sh::ShRgb));
            std::memcpy(message.data() + sizeof header + n * sizeof(sh::ShRgb),
                        valid.data() + begin, n);
        }
    }

    int m_rank;
    int m_size;
    DistributedTraffic m_traffic;
};

#endif // PROBEKIT_WITH_MPI

} // namespace

std::unique_ptr<DistributedBake> DistributedBake::join(int& argc, char**& argv) {
    int launched_size = 0;
    if (!launchedByMpi(&launched_size)) {
        return std::make_unique<SingleProcess>();
    }
#ifdef PROBEKIT_WITH_MPI
    int provided = 0;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided);
    int rank = 0;
    int size = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    auto job = std::make_unique<MpiJob>(rank, size);
    if (provided < MPI_THREAD_SERIALIZED) {
        job->abort("this MPI library does not allow MPI calls from a second thread "
                   "(MPI_THREAD_SERIALIZED), which the distributed bake needs");
    }
    return job;
#else
    (void)argc;
    (void)argv;
    if (launched_size > 1) {
        std::fprintf(stderr,
                     "probekit: warning: started by an MPI launcher with %d processes, "
                     "but this build has no MPI support (see docs/baking.md, Distributed "
                     "bakes): each process bakes alone\n",
                     launched_size);
    }
    return std::make_unique<SingleProcess>();
#endif
}

DistributedBake* currentJob() {
    return g_job;
}

void setCurrentJob(DistributedBake* job) {
    g_job = job;
}

} // namespace probekit::cli
