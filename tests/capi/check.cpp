// A C++ user of the C API (tests/capi.rs compiles it with the system c++ through
// pkg-config and compares its value with Rust's): the handle in a unique_ptr with
// surftile_free as its deleter, and the status checked as an enum.
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

#include "surftile.h"

using Surface = std::unique_ptr<surftile_surface, decltype(&surftile_free)>;

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: check-cpp SPEC\n");
        return 2;
    }
    surftile_surface* raw = nullptr;
    if (surftile_open(argv[1], 7, &raw) != SURFTILE_STATUS_OK) {
        std::fprintf(stderr, "surftile_open: %s\n", surftile_last_error());
        return 1;
    }
    Surface surface(raw, &surftile_free);
    const size_t w = 8, h = 4, c = surftile_channels(surface.get());
    std::vector<float> tile(w * h * c);
    if (surftile_fill(surface.get(), -5.0e7, 2.5, 1.0, w, h, tile.data(), w * c) !=
        SURFTILE_STATUS_OK) {
        std::fprintf(stderr, "surftile_fill: %s\n", surftile_last_error());
        return 1;
    }
    float v = surftile_height(surface.get(), -5.0e7 + 3.0, 2.5 + 1.0);
    std::uint32_t a, b;
    std::memcpy(&a, &v, sizeof a);
    std::memcpy(&b, &tile[(1 * w + 3) * c], sizeof b);
    std::printf("%08x %08x\n", a, b);
    return 0;
}
