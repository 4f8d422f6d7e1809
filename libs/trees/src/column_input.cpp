#include <forest_slam/core/atomic_file.h>
#include <forest_slam/trees/column_input.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <type_traits>

namespace forest_slam::trees
{
namespace
{
constexpr char kMagic[8] = {'F', 'S', 'C', 'O', 'L', 'I', 'N', '\0'};
constexpr uint32_t kVersion = 1;

template <class V>
void writeArray(std::ostream& out, const V& v)
{
	const uint64_t n = v.size();
	out.write(reinterpret_cast<const char*>(&n), sizeof n);
	out.write(reinterpret_cast<const char*>(v.data()),
	          std::streamsize(n * sizeof(v[0])));
}

/** Reads the arrays of one file, failing with its name. */
class Reader
{
   public:
	explicit Reader(const std::string& path)
	    : path_(path), in_(path, std::ios::binary)
	{
		if (!in_) fail("cannot open the file");
		in_.seekg(0, std::ios::end);
		left_ = uint64_t(in_.tellg());
		in_.seekg(0);
	}
	[[noreturn]] void fail(const std::string& what) const
	{
		throw std::runtime_error("column input " + path_ + ": " + what);
	}
	void bytes(void* dst, uint64_t n, const char* what)
	{
		if (n > left_)
			fail(std::string("truncated (") + what + ": " + std::to_string(n) +
			     " bytes expected, " + std::to_string(left_) + " left)");
		in_.read(static_cast<char*>(dst), std::streamsize(n));
		if (!in_) fail(std::string("read error in ") + what);
		left_ -= n;
	}
	template <class V>
	void array(V& v, const char* what)
	{
		uint64_t n = 0;
		bytes(&n, sizeof n, what);
		if (n > left_ / sizeof(v[0]))
			fail(std::string("truncated (") + what + ": " + std::to_string(n) +
			     " elements announced, " + std::to_string(left_) +
			     " bytes left)");
		v.resize(n);
		bytes(v.data(), n * sizeof(v[0]), what);
	}
	uint64_t left() const { return left_; }

   private:
	std::string path_;
	std::ifstream in_;
	uint64_t left_ = 0;
};

std::string sizesError(const ColumnInput& in)
{
	if (in.dirs.size() != in.pts.size() || in.times.size() != in.pts.size())
		return "pts, dirs and times differ in length (" +
		       std::to_string(in.pts.size()) + ", " +
		       std::to_string(in.dirs.size()) + ", " +
		       std::to_string(in.times.size()) + ")";
	const auto& s = in.seg;
	if (s.dirs.size() != s.pts.size() || s.segment.size() != s.pts.size() ||
	    (!s.range_class.empty() && s.range_class.size() != s.pts.size()))
		return "the segmented points' arrays differ in length";
	return "";
}
}  // namespace

void ColumnInput::clear()
{
	pts.clear(), ground.clear(), dirs.clear(), times.clear();
	seg.pts.clear(), seg.dirs.clear(), seg.segment.clear();
	seg.range_class.clear();
}

void ColumnInput::trim(size_t points)
{
	auto cut = [points](auto& v)
	{
		if (v.capacity() > points) std::decay_t<decltype(v)>().swap(v);
	};
	cut(pts), cut(ground), cut(dirs), cut(times);
	cut(seg.pts), cut(seg.dirs), cut(seg.segment), cut(seg.range_class);
}

std::vector<map::TreeRecord> detectColumnTrees(const ColumnInput& in,
                                               const TerrainModel& dtm,
                                               const TreeOptions& o)
{
	std::vector<map::TreeRecord> found;
	for (const auto& t :
	     detectTrees(in.pts, dtm, o, nullptr, &in.dirs,
	                 in.seg.pts.empty() ? nullptr : &in.seg, &in.times))
		if (t.record.x >= in.x0 && t.record.x < in.x0 + in.size_m &&
		    t.record.y >= in.y0 && t.record.y < in.y0 + in.size_m)
			found.push_back(t.record);
	return found;
}

void writeColumnInput(const std::string& path, const ColumnInput& in)
{
	const std::string bad = sizesError(in);
	if (!bad.empty())
		throw std::invalid_argument("writeColumnInput " + path + ": " + bad);
	core::writeFileAtomically(
	    path,
	    [&](std::ostream& out)
	    {
		    out.write(kMagic, sizeof kMagic);
		    out.write(reinterpret_cast<const char*>(&kVersion),
		              sizeof kVersion);
		    const double square[3] = {in.x0, in.y0, in.size_m};
		    out.write(reinterpret_cast<const char*>(square), sizeof square);
		    writeArray(out, in.ground), writeArray(out, in.pts);
		    writeArray(out, in.dirs), writeArray(out, in.times);
		    writeArray(out, in.seg.pts), writeArray(out, in.seg.dirs);
		    writeArray(out, in.seg.segment);
		    writeArray(out, in.seg.range_class);
	    },
	    true);
}

ColumnInput readColumnInput(const std::string& path)
{
	Reader r(path);
	char magic[sizeof kMagic];
	uint32_t version = 0;
	r.bytes(magic, sizeof magic, "header");
	if (std::memcmp(magic, kMagic, sizeof kMagic) != 0)
		r.fail("not a column input file (writeColumnInput)");
	r.bytes(&version, sizeof version, "header");
	if (version != kVersion)
		r.fail("version " + std::to_string(version) + ", expected " +
		       std::to_string(kVersion));
	ColumnInput in;
	double square[3];
	r.bytes(square, sizeof square, "header");
	in.x0 = square[0], in.y0 = square[1], in.size_m = square[2];
	r.array(in.ground, "ground"), r.array(in.pts, "pts");
	r.array(in.dirs, "dirs"), r.array(in.times, "times");
	r.array(in.seg.pts, "seg.pts"), r.array(in.seg.dirs, "seg.dirs");
	r.array(in.seg.segment, "seg.segment");
	r.array(in.seg.range_class, "seg.range_class");
	if (r.left() != 0)
		r.fail(std::to_string(r.left()) + " bytes after the last array");
	const std::string bad = sizesError(in);
	if (!bad.empty()) r.fail(bad);
	if (!(in.size_m > 0)) r.fail("the column's size must be > 0");
	return in;
}

}  // namespace forest_slam::trees
