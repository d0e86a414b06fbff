// OpenSubdiv reference for `cargo bench -p bidegree --bench opensubdiv` (built by
// scripts/bench_opensubdiv.sh, started by the bench). It owns nothing but the timing of
// OpenSubdiv's own uniform refinement, done exactly as a user of the Far API does it
// (far_tutorial_0 style):
//
//   fresh  = Far::TopologyRefinerFactory<TopologyDescriptor>::Create + RefineUniform(level)
//            + allocation of the primvar buffer + Far::PrimvarRefiner::Interpolate per level
//   cached = Far::PrimvarRefiner::Interpolate per level on the existing refiner and buffer
//
// Scheme catmark, boundary interpolation edge-only, no creases, float x/y/z positions, default
// UniformOptions (orderVerticesFromFacesFirst = false, fullTopologyInLastLevel = false).
//
// Usage: osd_driver CAGE.bin, then one request a line on stdin, one answer a line on stdout, so
// that the bench can interleave OpenSubdiv's samples with its own (the cage is parsed once):
//   fresh LEVEL SECONDS   -> osd fresh level=L faces=F ms=M topology_ms=M reps=R peak_rss_mib=X
//   cached LEVEL SECONDS  -> osd cached level=L faces=F ms=M reps=R peak_rss_mib=X
//   release               -> osd released
// ms is the median of R repetitions sized to take about SECONDS: one when a single run takes
// longer, else 3 to 21. The first sample of a (mode, level) starts with a warm-up run, which
// counts as the repetition when it took longer than SECONDS. `cached` keeps the refiner and buffer
// of its level for the next `cached` request; `fresh`, `release` or another level drop them (so
// the bench's own memory and OpenSubdiv's add up only while both sides hold cached data).
// topology_ms is Create + RefineUniform alone; peak_rss_mib is the process's peak so far.
// CAGE.bin (little endian, written by the Rust bench): u32 num_vertices, u32 num_faces,
// u32 face_sizes[num_faces], u32 face_vertices[sum of sizes], f32 points[3 * num_vertices].

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using namespace OpenSubdiv;

namespace {

// The primvar type the Far tutorials use: a position with Clear and AddWithWeight.
struct Vertex {
    float x, y, z;
    void Clear(void* = nullptr) { x = y = z = 0.0f; }
    void AddWithWeight(Vertex const& src, float w) {
        x += w * src.x;
        y += w * src.y;
        z += w * src.z;
    }
};

struct Cage {
    std::vector<int> sizes;
    std::vector<int> indices;
    std::vector<Vertex> points;
};

Cage read_cage(const char* path) {
    FILE* f = std::fopen(path, "rb");
    if (!f) {
        std::fprintf(stderr, "osd_driver: cannot open %s\n", path);
        std::exit(2);
    }
    auto read = [&](void* dst, size_t bytes) {
        if (bytes && std::fread(dst, 1, bytes, f) != bytes) {
            std::fprintf(stderr, "osd_driver: %s is truncated\n", path);
            std::exit(2);
        }
    };
    uint32_t header[2];
    read(header, sizeof header);
    Cage cage;
    std::vector<uint32_t> buf(header[1]);
    read(buf.data(), 4 * buf.size());
    cage.sizes.assign(buf.begin(), buf.end());
    size_t corners = 0;
    for (int s : cage.sizes) corners += s;
    buf.resize(corners);
    read(buf.data(), 4 * buf.size());
    cage.indices.assign(buf.begin(), buf.end());
    cage.points.resize(header[0]);
    read(cage.points.data(), 12 * cage.points.size());
    std::fclose(f);
    return cage;
}

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::unique_ptr<Far::TopologyRefiner> refine(const Cage& cage, int level) {
    using Descriptor = Far::TopologyDescriptor;
    using Factory = Far::TopologyRefinerFactory<Descriptor>;
    Sdc::Options options;
    options.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
    Descriptor desc;
    desc.numVertices = static_cast<int>(cage.points.size());
    desc.numFaces = static_cast<int>(cage.sizes.size());
    desc.numVertsPerFace = cage.sizes.data();
    desc.vertIndicesPerFace = cage.indices.data();
    std::unique_ptr<Far::TopologyRefiner> refiner(
        Factory::Create(desc, Factory::Options(Sdc::SCHEME_CATMARK, options)));
    if (!refiner) {
        std::fprintf(stderr, "osd_driver: TopologyRefinerFactory::Create failed\n");
        std::exit(2);
    }
    refiner->RefineUniform(Far::TopologyRefiner::UniformOptions(level));
    return refiner;
}

// Interpolates the cage points through every level into `buffer` (all levels, in order).
void interpolate(const Far::TopologyRefiner& refiner, const Cage& cage,
                 std::vector<Vertex>& buffer) {
    std::copy(cage.points.begin(), cage.points.end(), buffer.begin());
    Far::PrimvarRefiner primvar(refiner);
    Vertex* src = buffer.data();
    for (int level = 1; level <= refiner.GetMaxLevel(); ++level) {
        Vertex* dst = src + refiner.GetLevel(level - 1).GetNumVertices();
        primvar.Interpolate(level, src, dst);
        src = dst;
    }
}

// One fresh run; returns {total ms, topology ms} and keeps nothing.
std::pair<double, double> fresh_run(const Cage& cage, int level, int* faces) {
    auto t0 = Clock::now();
    auto refiner = refine(cage, level);
    double topology = ms_since(t0);
    std::vector<Vertex> buffer(refiner->GetNumVerticesTotal());
    interpolate(*refiner, cage, buffer);
    double total = ms_since(t0);
    *faces = refiner->GetLevel(level).GetNumFaces();
    volatile float sink = buffer.back().x;
    (void)sink;
    return {total, topology};
}

// Repetitions of a run of `run_ms` for a sample of about `target_s` (the bench's rule).
int repetitions(double run_ms, double target_s) {
    if (run_ms > target_s * 1e3) return 1;
    return std::clamp(static_cast<int>(target_s * 1e3 / std::max(run_ms, 1e-3)), 3, 21);
}

// Times `run` (returns ms) for one sample of about `target_s`; `estimate` is the run time of the
// previous sample of the same kind (0: none yet, so warm up first). Returns {median ms, reps}.
template <class Run>
std::pair<double, int> sample(double target_s, double& estimate, Run run) {
    std::vector<double> times;
    if (estimate <= 0) {
        double warmup = run();
        if (warmup > target_s * 1e3) times.push_back(warmup);
        estimate = warmup;
    }
    int reps = repetitions(estimate, target_s);
    while (static_cast<int>(times.size()) < reps) times.push_back(run());
    estimate = median(times);
    return {estimate, reps};
}

double peak_rss_mib() {
    struct rusage usage;
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_maxrss / 1024.0;
}

// The refiner and buffer that `cached` requests of one level reuse.
struct Held {
    int level = -1;
    std::unique_ptr<Far::TopologyRefiner> refiner;
    std::vector<Vertex> buffer;

    void release() {
        level = -1;
        refiner.reset();
        std::vector<Vertex>().swap(buffer);
    }
};

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s CAGE.bin (requests on stdin: fresh|cached LEVEL SECONDS, "
                             "release)\n", argv[0]);
        return 2;
    }
    Cage cage = read_cage(argv[1]);
    Held held;
    // Run-time estimates by (mode, level): 0 fresh, 1 cached.
    std::map<std::pair<int, int>, double> estimates;
    std::string line;
    while (std::getline(std::cin, line)) {
        std::istringstream request(line);
        std::string mode;
        int level = 0;
        double target_s = 0;
        request >> mode >> level >> target_s;
        if (mode == "release") {
            held.release();
            std::printf("osd released\n");
        } else if (mode == "fresh" && request) {
            held.release();
            int faces = 0;
            std::vector<double> topology;
            auto [ms, reps] = sample(target_s, estimates[{0, level}], [&] {
                auto [total, topo] = fresh_run(cage, level, &faces);
                topology.push_back(topo);
                return total;
            });
            // The warm-up's topology time when the warm-up was not one of the repetitions.
            if (static_cast<int>(topology.size()) > reps) topology.erase(topology.begin());
            std::printf("osd fresh level=%d faces=%d ms=%.4f topology_ms=%.4f reps=%d "
                        "peak_rss_mib=%.0f\n",
                        level, faces, ms, median(topology), reps, peak_rss_mib());
        } else if (mode == "cached" && request) {
            if (held.level != level) {
                held.release();
                held.refiner = refine(cage, level);
                held.buffer.resize(held.refiner->GetNumVerticesTotal());
                held.level = level;
                // Touches the new buffer's pages, outside the timing.
                interpolate(*held.refiner, cage, held.buffer);
            }
            auto [ms, reps] = sample(target_s, estimates[{1, level}], [&] {
                auto t0 = Clock::now();
                interpolate(*held.refiner, cage, held.buffer);
                return ms_since(t0);
            });
            std::printf("osd cached level=%d faces=%d ms=%.4f reps=%d peak_rss_mib=%.0f\n", level,
                        held.refiner->GetLevel(level).GetNumFaces(), ms, reps, peak_rss_mib());
        } else {
            std::fprintf(stderr, "osd_driver: bad request %s\n", line.c_str());
            return 2;
        }
        std::fflush(stdout);
    }
    return 0;
}
