// OpenSubdiv reference for `cargo bench -p bidegree --bench opensubdiv` (built and run by
// scripts/bench_opensubdiv.sh). It owns nothing but the timing of OpenSubdiv's own uniform
// refinement, done exactly as a user of the Far API does it (far_tutorial_0 style):
//
//   fresh  = Far::TopologyRefinerFactory<TopologyDescriptor>::Create + RefineUniform(level)
//            + allocation of the primvar buffer + Far::PrimvarRefiner::Interpolate per level
//   cached = Far::PrimvarRefiner::Interpolate per level on the existing refiner and buffer
//
// Scheme catmark, boundary interpolation edge-only, no creases, float x/y/z positions, default
// UniformOptions (orderVerticesFromFacesFirst = false, fullTopologyInLastLevel = false).
//
// Usage: osd_driver CAGE.bin LEVEL[,LEVEL...] [TARGET_SECONDS]
// CAGE.bin (little endian, written by the Rust bench): u32 num_vertices, u32 num_faces,
// u32 face_sizes[num_faces], u32 face_vertices[sum of sizes], f32 points[3 * num_vertices].
// Prints one line per level:
//   osd level=L faces=F fresh_ms=M cached_ms=M topology_ms=M reps=R peak_rss_mib=X
// (medians over R repetitions after one warm-up, which counts as the first repetition when it
// took longer than TARGET_SECONDS, default 1; topology_ms is Create + RefineUniform alone).

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
#include <memory>
#include <string>
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

int repetitions(double warmup_ms, double target_s) {
    int reps = static_cast<int>(target_s * 1e3 / std::max(warmup_ms, 1e-3));
    return std::clamp(reps, 3, 21);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: %s CAGE.bin LEVEL[,LEVEL...] [TARGET_SECONDS]\n", argv[0]);
        return 2;
    }
    Cage cage = read_cage(argv[1]);
    double target_s = argc > 3 ? std::atof(argv[3]) : 1.0;
    std::string list = argv[2];
    for (size_t at = 0; at < list.size();) {
        size_t comma = list.find(',', at);
        if (comma == std::string::npos) comma = list.size();
        int level = std::atoi(list.substr(at, comma - at).c_str());
        at = comma + 1;

        int faces = 0;
        auto warmup = fresh_run(cage, level, &faces);
        int reps = repetitions(warmup.first, target_s);
        std::vector<double> fresh, topology, cached;
        // A warm-up longer than the target counts as the first sample (keeps big levels short).
        bool long_warmup = warmup.first > target_s * 1e3;
        if (long_warmup) {
            fresh.push_back(warmup.first);
            topology.push_back(warmup.second);
        }
        for (int r = long_warmup ? 1 : 0; r < reps; ++r) {
            auto [t, topo] = fresh_run(cage, level, &faces);
            fresh.push_back(t);
            topology.push_back(topo);
        }
        {
            auto refiner = refine(cage, level);
            std::vector<Vertex> buffer(refiner->GetNumVerticesTotal());
            auto t0 = Clock::now();
            interpolate(*refiner, cage, buffer);  // warm-up
            double first = ms_since(t0);
            if (first > target_s * 1e3) cached.push_back(first);
            for (int r = first > target_s * 1e3 ? 1 : 0; r < reps; ++r) {
                auto t0 = Clock::now();
                interpolate(*refiner, cage, buffer);
                cached.push_back(ms_since(t0));
            }
        }
        struct rusage usage;
        getrusage(RUSAGE_SELF, &usage);
        std::printf("osd level=%d faces=%d fresh_ms=%.4f cached_ms=%.4f topology_ms=%.4f reps=%d "
                    "peak_rss_mib=%.0f\n",
                    level, faces, median(fresh), median(cached), median(topology), reps,
                    usage.ru_maxrss / 1024.0);
        std::fflush(stdout);
    }
    return 0;
}
