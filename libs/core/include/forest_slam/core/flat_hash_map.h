#pragma once
// A hash map from 63-bit integer keys (packed voxel or cell indices) to
// values, for the per-point lookups of the map and the odometry's local map:
// open addressing with linear probing in one power-of-two array, at most 5/8
// full. A scan adds or queries tens of thousands of points, one lookup each;
// std::unordered_map's node chasing (a cache miss per node) was the largest
// single cost of a mapping run (perf: 17 % of the CPU in the voxel map's
// lookups, 17 % in the local map's).
//
// Values live in the table: a pointer to one is valid until the table grows
// (reserve() first to add without growing) or is rebuilt (eraseIf, clear).
// Iteration order is the table order: deterministic for a given sequence of
// operations, not sorted.
#include <forest_slam/core/memory.h>

#include <cstdint>
#include <utility>
#include <vector>

namespace forest_slam::core
{
/** Three signed cell indices in 21 bits each (+-1,048,575 cells): the low 63
 * bits of a key; the top bit stays clear (the table's empty marker). */
inline uint64_t packCellKey(int64_t i, int64_t j, int64_t k)
{
	constexpr uint64_t m = (uint64_t(1) << 21) - 1;
	return ((static_cast<uint64_t>(i) & m) << 42) |
	       ((static_cast<uint64_t>(j) & m) << 21) |
	       (static_cast<uint64_t>(k) & m);
}
/** The index of axis a (0, 1, 2 = i, j, k) of a packed key, sign-extended. */
inline int32_t unpackCellIndex(uint64_t key, int a)
{
	const uint64_t v = (key >> (42 - 21 * a)) & ((uint64_t(1) << 21) - 1);
	return static_cast<int32_t>(v << 11) >> 11;
}

/** Asks the CPU to load the cache line holding p (a hint: no effect on the
 * program's results). Tables larger than the caches are bound by memory
 * latency; a bulk pass that asks a few items ahead overlaps those loads. */
inline void prefetchLine(const void* p)
{
#if defined(__x86_64__)
	// GCC 12 deems a function whose only effect is __builtin_prefetch
	// "pure" and drops calls to it: the volatile asm keeps it.
	asm volatile("prefetcht0 %0" : : "m"(*static_cast<const char*>(p)));
#else
	__builtin_prefetch(p);
#endif
}

/** splitmix64's finaliser: neighbouring cells land far apart (linear
 * probing degrades on runs of nearby hashes). */
inline uint64_t mixKey(uint64_t h)
{
	h ^= h >> 30;
	h *= 0xbf58476d1ce4e5b9ull;
	h ^= h >> 27;
	h *= 0x94d049bb133111ebull;
	return h ^ (h >> 31);
}

template <class V>
class FlatHashMap
{
   public:
	static constexpr uint64_t kEmpty = ~uint64_t(0);

	size_t size() const { return size_; }
	bool empty() const { return size_ == 0; }
	void clear()
	{
		std::vector<Slot>().swap(slots_);
		size_ = 0;
	}
	/** Empties the table but keeps its slots: refilling it to the same size
	 * neither allocates nor faults pages in again. */
	void clearKeepingCapacity()
	{
		for (Slot& s : slots_) s = Slot{};
		size_ = 0;
	}
	/** Table bytes (values' own heap memory not included). */
	size_t memoryBytes() const { return vectorBytes(slots_); }

	/** Makes room for n entries in all: no growth (pointers to values stay
	 * valid) while size() <= n. */
	void reserve(size_t n)
	{
		size_t cap = slots_.empty() ? 64 : slots_.size();
		while (8 * n > 5 * cap) cap *= 2;
		if (cap != slots_.size()) rehash(cap);
	}

	V* find(uint64_t k)
	{
		return const_cast<V*>(static_cast<const FlatHashMap*>(this)->find(k));
	}
	const V* find(uint64_t k) const
	{
		if (slots_.empty()) return nullptr;
		const size_t mask = slots_.size() - 1;
		for (size_t i = mixKey(k) & mask;; i = (i + 1) & mask)
		{
			const Slot& s = slots_[i];
			if (s.key == k) return &s.value;
			if (s.key == kEmpty) return nullptr;
		}
	}
	/** Asks the CPU to load k's first slot (prefetchLine): only a hint,
	 * no effect on the contents. */
	void prefetch(uint64_t k) const
	{
		if (slots_.empty()) return;
		prefetchLine(&slots_[mixKey(k) & (slots_.size() - 1)]);
	}
	/** The value of k, default-constructed if new; `added` says which. */
	V& tryEmplace(uint64_t k, bool* added = nullptr)
	{
		if (8 * (size_ + 1) > 5 * slots_.size())
			rehash(slots_.empty() ? 64 : 2 * slots_.size());
		const size_t mask = slots_.size() - 1;
		for (size_t i = mixKey(k) & mask;; i = (i + 1) & mask)
		{
			Slot& s = slots_[i];
			if (s.key == k)
			{
				if (added) *added = false;
				return s.value;
			}
			if (s.key == kEmpty)
			{
				s.key = k;
				size_++;
				if (added) *added = true;
				return s.value;
			}
		}
	}
	V& operator[](uint64_t k) { return tryEmplace(k); }

	/** f(key, value) for every entry. */
	template <class F>
	void forEach(F&& f) const
	{
		for (const Slot& s : slots_)
			if (s.key != kEmpty) f(s.key, s.value);
	}
	/** Drops the entries for which pred(key, value) holds (rebuilds the
	 * table: linear probing has no cheap single erase). */
	template <class Pred>
	void eraseIf(Pred&& pred)
	{
		std::vector<Slot> old;
		old.swap(slots_);
		size_ = 0;
		size_t keep = 0;
		for (const Slot& s : old)
			if (s.key != kEmpty && !pred(s.key, s.value)) keep++;
		if (keep == 0) return;
		reserve(keep);
		for (Slot& s : old)
			if (s.key != kEmpty && !pred(s.key, s.value))
				place(s.key, std::move(s.value));
	}

   private:
	struct Slot
	{
		uint64_t key = kEmpty;
		V value{};
	};
	void place(uint64_t k, V&& v)
	{
		const size_t mask = slots_.size() - 1;
		size_t i = mixKey(k) & mask;
		while (slots_[i].key != kEmpty) i = (i + 1) & mask;
		slots_[i].key = k;
		slots_[i].value = std::move(v);
		size_++;
	}
	void rehash(size_t cap)
	{
		std::vector<Slot> old(cap);
		old.swap(slots_);
		size_ = 0;
		for (Slot& s : old)
			if (s.key != kEmpty) place(s.key, std::move(s.value));
	}

	std::vector<Slot> slots_;
	size_t size_ = 0;
};

}  // namespace forest_slam::core
