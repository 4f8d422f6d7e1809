#pragma once
// Deterministic random numbers. std:: distributions are implementation
// defined, so a seed would give another forest with another standard library;
// these fixed algorithms (xoshiro256**, SplitMix64, Box-Muller) do not.
//
// Two flavours: a sequential generator for building the world, and stateless
// hashes for per-ray noise, so that a ray's noise depends only on (seed, scan,
// column, row) and not on which thread cast it or in which order.
#include <cmath>
#include <cstdint>

namespace forest_slam::sim
{
/** SplitMix64 finaliser: a strong 64-bit mix. */
inline uint64_t mix64(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ULL;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
	return x ^ (x >> 31);
}

inline uint64_t hashCombine(uint64_t a, uint64_t b)
{
	return mix64(a ^ (mix64(b) + 0x632be59bd9b4e019ULL));
}

/** Uniform in [0,1) from a hash (53 random bits). */
inline double hashUniform(uint64_t h)
{
	return static_cast<double>(mix64(h) >> 11) * (1.0 / 9007199254740992.0);
}

/** Standard normal from a hash (Box-Muller on two derived uniforms). */
inline double hashNormal(uint64_t h)
{
	const double u1 = 1.0 - hashUniform(h);  // (0,1]
	const double u2 = hashUniform(h ^ 0x5851f42d4c957f2dULL);
	return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

class Rng
{
   public:
	explicit Rng(uint64_t seed)
	{
		uint64_t x = seed;
		for (auto& w : s_) w = x = mix64(x);
	}

	/** An independent generator for a named sub-task (terrain, trees...):
	 * adding a draw in one sub-task must not reshuffle the others. */
	Rng fork(uint64_t stream) const
	{
		return Rng(hashCombine(s_[0] ^ s_[2], stream));
	}

	uint64_t next()
	{
		const uint64_t r = rotl(s_[1] * 5, 7) * 9;
		const uint64_t t = s_[1] << 17;
		s_[2] ^= s_[0];
		s_[3] ^= s_[1];
		s_[1] ^= s_[2];
		s_[0] ^= s_[3];
		s_[2] ^= t;
		s_[3] = rotl(s_[3], 45);
		return r;
	}
	/** [0,1) */
	double uniform()
	{
		return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0);
	}
	double uniform(double a, double b) { return a + (b - a) * uniform(); }
	/** 0..n-1 */
	int uniformInt(int n)
	{
		return static_cast<int>(uniform() * n) % (n > 0 ? n : 1);
	}
	double normal()
	{
		if (has_spare_)
		{
			has_spare_ = false;
			return spare_;
		}
		const double u1 = 1.0 - uniform();
		const double u2 = uniform();
		const double r = std::sqrt(-2.0 * std::log(u1));
		spare_ = r * std::sin(2.0 * M_PI * u2);
		has_spare_ = true;
		return r * std::cos(2.0 * M_PI * u2);
	}
	double normal(double mean, double sigma) { return mean + sigma * normal(); }
	/** Log-normal with the given median and sigma of log. */
	double lognormal(double median, double sigma_log)
	{
		return median * std::exp(sigma_log * normal());
	}

   private:
	static uint64_t rotl(uint64_t x, int k)
	{
		return (x << k) | (x >> (64 - k));
	}
	uint64_t s_[4];
	double spare_ = 0;
	bool has_spare_ = false;
};

}  // namespace forest_slam::sim
