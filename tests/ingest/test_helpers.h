#pragma once
// Shared helpers of the ingest tests: temp dirs, a PCD reader, nearest-point
// statistics, a small CDR encoder (the ROS 2 side of the message tests).
#include <unistd.h>
#include <nanoflann.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace ingest_test
{
inline std::string sharedData(const std::string& rel)
{
	return std::string(FOREST_SLAM_SHARED_DIR) + "/data/" + rel;
}

/** A fresh directory under the system temp dir, removed at destruction. */
struct TempDir
{
	std::filesystem::path path;
	explicit TempDir(const std::string& tag)
	{
		path = std::filesystem::temp_directory_path() /
		       ("fs_ingest_" + tag + "_" + std::to_string(::getpid()));
		std::filesystem::remove_all(path);
		std::filesystem::create_directories(path);
	}
	~TempDir() { std::filesystem::remove_all(path); }
	std::string operator/(const std::string& f) const
	{
		return (path / f).string();
	}
};

struct Pcd
{
	std::vector<std::string> fields;
	std::vector<std::vector<double>> columns;  ///< per field
	size_t size() const { return columns.empty() ? 0 : columns[0].size(); }
	const std::vector<double>& col(const std::string& name) const
	{
		for (size_t i = 0; i < fields.size(); i++)
			if (fields[i] == name) return columns[i];
		throw std::runtime_error("PCD has no field " + name);
	}
};

/** Binary PCD v0.7 (COUNT 1 fields), enough for the reference files. */
inline Pcd readPcd(const std::string& path)
{
	std::ifstream f(path, std::ios::binary);
	if (!f) throw std::runtime_error("cannot open " + path);
	Pcd pcd;
	std::vector<int> sizes;
	std::vector<char> types;
	size_t n = 0;
	std::string line, data;
	while (std::getline(f, line))
	{
		std::istringstream is(line);
		std::string k;
		is >> k;
		if (k == "FIELDS")
			for (std::string x; is >> x;) pcd.fields.push_back(x);
		else if (k == "SIZE")
			for (int x; is >> x;) sizes.push_back(x);
		else if (k == "TYPE")
			for (char x; is >> x;) types.push_back(x);
		else if (k == "POINTS")
			is >> n;
		else if (k == "DATA")
		{
			is >> data;
			break;
		}
	}
	if (data != "binary") throw std::runtime_error(path + ": only binary PCD");
	size_t step = 0;
	for (int s : sizes) step += s;
	std::vector<char> buf(step * n);
	f.read(buf.data(), static_cast<std::streamsize>(buf.size()));
	if (static_cast<size_t>(f.gcount()) != buf.size())
		throw std::runtime_error(path + ": truncated");
	pcd.columns.assign(pcd.fields.size(), std::vector<double>(n));
	for (size_t i = 0; i < n; i++)
	{
		size_t off = 0;
		for (size_t j = 0; j < pcd.fields.size(); j++)
		{
			const char* q = buf.data() + i * step + off;
			double v = 0;
			if (types[j] == 'F' && sizes[j] == 4)
			{
				float x;
				std::memcpy(&x, q, 4);
				v = x;
			}
			else if (types[j] == 'F')
			{
				std::memcpy(&v, q, 8);
			}
			else if (sizes[j] == 1)
				v = static_cast<uint8_t>(*q);
			else if (sizes[j] == 2)
			{
				uint16_t x;
				std::memcpy(&x, q, 2);
				v = x;
			}
			else
			{
				uint32_t x;
				std::memcpy(&x, q, 4);
				v = x;
			}
			pcd.columns[j][i] = v;
			off += sizes[j];
		}
	}
	return pcd;
}

struct Cloud
{
	std::vector<std::array<float, 3>> pts;
	size_t kdtree_get_point_count() const { return pts.size(); }
	float kdtree_get_pt(size_t i, int d) const { return pts[i][d]; }
	template <class B>
	bool kdtree_get_bbox(B&) const
	{
		return false;
	}
};

/** Fraction of `query` points with a point of `ref` within `tol_m`. */
inline double fractionWithin(const Cloud& ref, const Cloud& query, double tol_m)
{
	using Tree = nanoflann::KDTreeSingleIndexAdaptor<
	    nanoflann::L2_Simple_Adaptor<float, Cloud>, Cloud, 3>;
	if (query.pts.empty() || ref.pts.empty()) return 0;
	Tree tree(3, ref, nanoflann::KDTreeSingleIndexAdaptorParams(10));
	tree.buildIndex();
	size_t ok = 0;
	for (const auto& p : query.pts)
	{
		size_t idx;
		float d2;
		nanoflann::KNNResultSet<float> rs(1);
		rs.init(&idx, &d2);
		tree.findNeighbors(rs, p.data(), nanoflann::SearchParams());
		if (d2 <= tol_m * tol_m) ok++;
	}
	return static_cast<double>(ok) / query.pts.size();
}

/** Minimal CDR (little-endian) writer following the alignment rules, to
 * produce ROS 2 payloads independently of the decoder under test. */
class CdrWriter
{
   public:
	CdrWriter() { buf_ = {0x00, 0x01, 0x00, 0x00}; }
	void align(size_t n)
	{
		while ((buf_.size() - 4) % n) buf_.push_back(0);
	}
	template <typename T>
	void put(T v)
	{
		align(sizeof(T));
		const auto* p = reinterpret_cast<const uint8_t*>(&v);
		buf_.insert(buf_.end(), p, p + sizeof(T));
	}
	void str(const std::string& s)
	{
		put<uint32_t>(static_cast<uint32_t>(s.size() + 1));
		buf_.insert(buf_.end(), s.begin(), s.end());
		buf_.push_back(0);
	}
	void time(int32_t sec, uint32_t nsec)
	{
		put<int32_t>(sec);
		put<uint32_t>(nsec);
	}
	void header(int32_t sec, uint32_t nsec, const std::string& frame)
	{
		time(sec, nsec);
		str(frame);
	}
	void bytes(const uint8_t* p, size_t n)
	{
		buf_.insert(buf_.end(), p, p + n);
	}
	const std::vector<uint8_t>& data() const { return buf_; }

   private:
	std::vector<uint8_t> buf_;
};

}  // namespace ingest_test
