// Counter-based random streams: every (seed, stream, sample) triple starts its own PCG32
// generator, so results do not depend on which thread computed which sample.
#pragma once
#include <cstdint>

namespace photic {

inline uint64_t mix64(uint64_t z) {  // SplitMix64 finaliser
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

class Rng {
public:
    Rng(uint64_t seed, uint64_t stream, uint64_t sample) {
        uint64_t h = mix64(seed ^ mix64(stream ^ mix64(sample)));
        inc_ = (mix64(h + 0x632be59bd9b4e019ull) << 1u) | 1u;
        state_ = 0;
        next_u32();
        state_ += h;
        next_u32();
    }
    uint32_t next_u32() {
        uint64_t old = state_;
        state_ = old * 6364136223846793005ull + inc_;
        uint32_t xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
        uint32_t rot = static_cast<uint32_t>(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
    }
    // Uniform in [0, 1) with 53 random bits.
    double uniform() {
        uint64_t hi = next_u32(), lo = next_u32();
        return static_cast<double>(((hi << 32) | lo) >> 11) * (1.0 / 9007199254740992.0);
    }
private:
    uint64_t state_, inc_;
};

}  // namespace photic
