// Counter-based random streams: every (seed, stream, sample) triple starts its own
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

// xoshiro256+ (Blackman & Vigna): 64 bits per call, the top 53 make a double.
class Rng {
public:
    Rng(uint64_t seed, uint64_t stream, uint64_t sample) {
        uint64_t h = mix64(seed ^ mix64(stream ^ mix64(sample)));
        for (auto& w : s_) { h += 0x9e3779b97f4a7c15ull; w = mix64(h); }
    }
    uint64_t next() {
        const uint64_t result = s_[0] + s_[3];
        const uint64_t t = s_[1] << 17;
        s_[2] ^= s_[0]; s_[3] ^= s_[1]; s_[1] ^= s_[2]; s_[0] ^= s_[3];
        s_[2] ^= t;
        s_[3] = (s_[3] << 45) | (s_[3] >> 19);
        return result;
    }
    // Uniform in [0, 1) with 53 random bits.
    double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
private:
    uint64_t s_[4];
};

}  // namespace photic
