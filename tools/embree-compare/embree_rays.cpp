// Times Embree on the rays of celray's helmet_rays case, on this machine:
// the same world-space triangles and the same rays, one ray per call
// (rtcIntersect1 / rtcOccluded1, no packets), on 1 and 2 threads. Checks
// that Embree finds the hits celray found (same hit or miss, t within a
// relative 1e-4), so the two figures are for the same work.
//
// Input: the file `celray bench rays --export-rays FILE` writes (format in
// src/bench/export.rs). Output: one JSON object per line.
// Build and run: tools/embree-compare/run.sh.

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <thread>
#include <vector>

namespace {

struct Input {
    std::vector<float> triangles;  // 9 floats each
    std::vector<float> rays;       // origin, direction: 6 floats each
    std::vector<float> celray_t;   // +inf on a miss
};

bool read_input(const char* path, Input& in) {
    std::ifstream f(path, std::ios::binary);
    char magic[8];
    uint32_t counts[2];
    if (!f.read(magic, 8) || std::memcmp(magic, "CELRAYS1", 8) != 0 ||
        !f.read(reinterpret_cast<char*>(counts), sizeof counts)) {
        std::fprintf(stderr, "%s: not a file written by celray bench --export-rays\n", path);
        return false;
    }
    in.triangles.resize(size_t(counts[0]) * 9);
    in.rays.resize(size_t(counts[1]) * 6);
    in.celray_t.resize(counts[1]);
    auto get = [&](std::vector<float>& v) {
        return bool(f.read(reinterpret_cast<char*>(v.data()), std::streamsize(v.size() * sizeof(float))));
    };
    if (!get(in.triangles) || !get(in.rays) || !get(in.celray_t)) {
        std::fprintf(stderr, "%s: truncated\n", path);
        return false;
    }
    return true;
}

double now_ms() {
    using namespace std::chrono;
    return duration<double, std::milli>(steady_clock::now().time_since_epoch()).count();
}

// Traces every ray on `threads` threads (blocks of 256 rays taken in turn);
// `t_out` gets each closest hit (+inf on a miss), or with `occluded` 0/1.
double trace_all(RTCScene scene, const Input& in, unsigned threads, bool occluded, std::vector<float>& t_out) {
    const size_t n = in.celray_t.size();
    t_out.assign(n, INFINITY);
    std::atomic<size_t> next{0};
    auto work = [&]() {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (;;) {
            size_t begin = next.fetch_add(256);
            if (begin >= n) {
                break;
            }
            size_t end = std::min(n, begin + 256);
            for (size_t i = begin; i < end; i++) {
                const float* r = &in.rays[i * 6];
                RTCRayHit rh;
                rh.ray.org_x = r[0];
                rh.ray.org_y = r[1];
                rh.ray.org_z = r[2];
                rh.ray.dir_x = r[3];
                rh.ray.dir_y = r[4];
                rh.ray.dir_z = r[5];
                rh.ray.tnear = 0.0f;
                rh.ray.tfar = INFINITY;
                rh.ray.time = 0.0f;
                rh.ray.mask = 0xffffffffu;
                rh.ray.id = 0;
                rh.ray.flags = 0;
                if (occluded) {
                    rtcOccluded1(scene, &ctx, &rh.ray);
                    t_out[i] = rh.ray.tfar < 0.0f ? 1.0f : 0.0f;
                } else {
                    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                    rtcIntersect1(scene, &ctx, &rh);
                    t_out[i] = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? INFINITY : rh.ray.tfar;
                }
            }
        }
    };
    double start = now_ms();
    std::vector<std::thread> pool;
    for (unsigned k = 1; k < threads; k++) {
        pool.emplace_back(work);
    }
    work();
    for (auto& t : pool) {
        t.join();
    }
    return now_ms() - start;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s FILE (written by celray bench rays --export-rays FILE)\n", argv[0]);
        return 2;
    }
    Input in;
    if (!read_input(argv[1], in)) {
        return 1;
    }
    RTCDevice device = rtcNewDevice("threads=2");
    if (!device) {
        std::fprintf(stderr, "rtcNewDevice failed\n");
        return 1;
    }
    const size_t tris = in.triangles.size() / 9;
    double build_start = now_ms();
    RTCScene scene = rtcNewScene(device);
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), tris * 3));
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                               3 * sizeof(unsigned), tris));
    std::memcpy(v, in.triangles.data(), in.triangles.size() * sizeof(float));
    for (size_t i = 0; i < tris * 3; i++) {
        idx[i] = unsigned(i);
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene);
    double build_ms = now_ms() - build_start;

    // Same answers: hit or miss agree, and t within a relative 1e-4 (float
    // rounding of two different triangle tests; a different triangle hit
    // at a shared edge lands at the same t).
    std::vector<float> t;
    trace_all(scene, in, 2, false, t);
    size_t agree = 0, hits = 0;
    for (size_t i = 0; i < t.size(); i++) {
        float a = t[i], b = in.celray_t[i];
        bool same = std::isinf(a) ? std::isinf(b) : (!std::isinf(b) && std::fabs(a - b) <= 1e-4f * std::max(1.0f, b));
        agree += same;
        hits += !std::isinf(a);
        if (!same && i + 1 - agree <= 5) {
            std::fprintf(stderr, "ray %zu (pixel %zu): Embree t %g, celray t %g\n", i, i, a, b);
        }
    }
    const double rays = double(t.size());
    std::printf("{\"case\": \"embree_setup\", \"embree\": \"%d.%d.%d\", \"triangles\": %zu, \"rays\": %zu, "
                "\"hits\": %zu, \"disagree_with_celray\": %zu, \"build_ms\": %.2f}\n",
                RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH, tris, t.size(), hits, t.size() - agree,
                build_ms);
    for (unsigned threads : {1u, 2u}) {
        for (bool occluded : {false, true}) {
            double best = 1e300;
            for (int run = 0; run < 7; run++) {
                best = std::min(best, trace_all(scene, in, threads, occluded, t));
            }
            std::printf("{\"case\": \"embree_%s_%ut\", \"ms\": %.3f, \"mrays_per_s\": %.2f}\n",
                        occluded ? "occluded" : "closest", threads, best, rays / best / 1e3);
        }
    }
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    return 0;
}
