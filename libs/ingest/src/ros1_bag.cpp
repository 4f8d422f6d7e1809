// ROS 1 bags. Indexed bags go through librosbag-storage (rosbag::View gives
// time order across topics). A bag whose index is missing (the recorder was
// killed, the file was cut) cannot be opened by librosbag at all, so we then
// walk the records ourselves, which is simple for format 2.0: each record is
// <uint32 header_len><header fields "name=value"><uint32 data_len><data>.
#include <forest_slam/core/log.h>
#include <forest_slam/ingest/bag_reader.h>

#include <bzlib.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <roslz4/lz4s.h>

#include <cstring>
#include <fstream>
#include <map>
#include <set>

namespace forest_slam::ingest
{
namespace
{
constexpr const char* kMagic = "#ROSBAG V2.0\n";
constexpr size_t kMagicLen = 13;

TopicInfo makeTopic(const std::string& name, const std::string& type,
                    const std::string& md5)
{
	TopicInfo t;
	t.name = name;
	t.type = type;
	t.kind = kindOfType(type);
	t.md5 = md5;
	t.serialization = "ros1";
	return t;
}

// ------------------------------------------------------------ indexed bags
class Ros1IndexedReader : public BagReader
{
   public:
	Ros1IndexedReader(const std::string& path, std::unique_ptr<rosbag::Bag> bag)
	    : BagReader(path), bag_(std::move(bag))
	{
		rosbag::View all(*bag_);
		std::map<std::string, size_t> by_name;
		for (const auto* c : all.getConnections())
		{
			if (by_name.count(c->topic))
			{
				const auto& t = topics_[by_name[c->topic]];
				if (t.type != c->datatype)
					throw BagError("bag '" + path + "': topic " + c->topic +
					                   " is recorded with two types (" +
					                   t.type + " and " + c->datatype + ")",
					               c->topic);
				continue;
			}
			by_name[c->topic] = topics_.size();
			topics_.push_back(makeTopic(c->topic, c->datatype, c->md5sum));
		}
		for (auto& t : topics_)
		{
			rosbag::View v(*bag_, rosbag::TopicQuery(t.name));
			t.count = v.size();
			if (t.count > 0)
			{
				t.first_ns = static_cast<int64_t>(v.getBeginTime().toNSec());
				t.last_ns = static_cast<int64_t>(v.getEndTime().toNSec());
			}
		}
	}

	BagFormat format() const override { return BagFormat::Ros1; }
	const std::vector<TopicInfo>& topics() const override { return topics_; }

	void select(const std::vector<std::string>& names) override
	{
		selected_ = names;
		total_ = 0;
		for (const auto& n : names)
			if (const auto* t = findTopic(n)) total_ += t->count;
	}

	bool next(BagMessage& out) override
	{
		if (!view_)
		{
			view_ = std::make_unique<rosbag::View>(
			    *bag_, rosbag::TopicQuery(selected_));
			it_ = view_->begin();
		}
		else if (it_ != view_->end())
			++it_;
		if (it_ == view_->end()) return false;
		const rosbag::MessageInstance& mi = *it_;
		const std::string& topic = mi.getTopic();
		const TopicInfo* info = findTopic(topic);
		const uint64_t index = per_topic_[topic]++;
		consumed_++;
		try
		{
			const uint32_t n = mi.size();
			buf_.resize(n);
			ros::serialization::OStream s(buf_.data(), n);
			mi.write(s);
		}
		catch (const std::exception& e)
		{
			throw BagError("bag '" + path_ + "': cannot read message #" +
			                   std::to_string(index) + " of topic " + topic +
			                   ": " + e.what(),
			               topic, static_cast<int64_t>(index));
		}
		out.topic = info;
		out.index = index;
		out.time_ns = static_cast<int64_t>(mi.getTime().toNSec());
		out.data = buf_.data();
		out.size = buf_.size();
		out.wire = Wire::Ros1;
		return true;
	}

	double fractionRead() const override
	{
		return total_ ? static_cast<double>(consumed_) / total_ : 1.0;
	}

   private:
	std::unique_ptr<rosbag::Bag> bag_;
	std::vector<TopicInfo> topics_;
	std::vector<std::string> selected_;
	std::unique_ptr<rosbag::View> view_;
	rosbag::View::iterator it_;
	std::map<std::string, uint64_t> per_topic_;
	std::vector<uint8_t> buf_;
	uint64_t total_ = 0, consumed_ = 0;
};

// --------------------------------------------------------- sequential scan
using Fields = std::map<std::string, std::string>;

/** Parses "len name=value" header fields; false if malformed. */
bool parseFields(const uint8_t* p, size_t n, Fields& out)
{
	out.clear();
	size_t i = 0;
	while (i < n)
	{
		if (n - i < 4) return false;
		uint32_t len;
		std::memcpy(&len, p + i, 4);
		i += 4;
		if (len > n - i) return false;
		const std::string f(reinterpret_cast<const char*>(p + i), len);
		i += len;
		const auto eq = f.find('=');
		if (eq == std::string::npos) return false;
		out[f.substr(0, eq)] = f.substr(eq + 1);
	}
	return true;
}

uint32_t fieldU32(const Fields& f, const char* name)
{
	auto it = f.find(name);
	if (it == f.end() || it->second.size() != 4) return UINT32_MAX;
	uint32_t v;
	std::memcpy(&v, it->second.data(), 4);
	return v;
}

int64_t fieldTimeNs(const Fields& f)
{
	auto it = f.find("time");
	if (it == f.end() || it->second.size() != 8) return 0;
	uint32_t s, ns;
	std::memcpy(&s, it->second.data(), 4);
	std::memcpy(&ns, it->second.data() + 4, 4);
	return static_cast<int64_t>(s) * 1000000000LL + ns;
}

/** One record from a byte range; false if it does not fit entirely. */
bool takeRecord(const uint8_t* p, size_t n, size_t& pos, Fields& fields,
                const uint8_t*& data, uint32_t& data_len)
{
	if (n - pos < 4) return false;
	uint32_t hl;
	std::memcpy(&hl, p + pos, 4);
	if (hl > n - pos - 4) return false;
	if (!parseFields(p + pos + 4, hl, fields)) return false;
	size_t q = pos + 4 + hl;
	if (n - q < 4) return false;
	std::memcpy(&data_len, p + q, 4);
	if (data_len > n - q - 4) return false;
	data = p + q + 4;
	pos = q + 4 + data_len;
	return true;
}

class Ros1SequentialReader : public BagReader
{
   public:
	explicit Ros1SequentialReader(const std::string& path) : BagReader(path)
	{
		// Pass 1: topics, counts and where the damage is. Pass 2 (next())
		// re-reads from the start: a truncated bag is a recovery case, not
		// the fast path.
		rewind();
		Item item;
		while (step(item, nullptr))
		{
			auto& t = topics_[topic_of_conn_.at(item.conn)];
			if (t.count == 0) t.first_ns = item.time_ns;
			t.first_ns = std::min(t.first_ns, item.time_ns);
			t.last_ns = std::max(t.last_ns, item.time_ns);
			t.count++;
			last_topic_ = t.name;
			last_index_ = t.count - 1;
		}
		damage_ = scan_error_;
		if (!damage_.empty() && !last_topic_.empty())
			damage_ += " (last complete message: #" +
			           std::to_string(last_index_) + " of " + last_topic_ + ")";
		scan_done_ = true;
		rewind();
	}

	BagFormat format() const override { return BagFormat::Ros1; }
	const std::vector<TopicInfo>& topics() const override { return topics_; }
	std::string damage() const override { return damage_; }

	void select(const std::vector<std::string>& names) override
	{
		selected_ = std::set<std::string>(names.begin(), names.end());
	}

	bool next(BagMessage& out) override
	{
		Item item;
		while (step(item, &out))
		{
			const auto& t = topics_[topic_of_conn_.at(item.conn)];
			const uint64_t index = per_topic_[t.name]++;
			if (!selected_.count(t.name)) continue;
			out.topic = &t;
			out.index = index;
			out.time_ns = item.time_ns;
			out.wire = Wire::Ros1;
			return true;
		}
		if (!scan_error_.empty())
			throw BagError("bag '" + path_ + "': " + damage_, last_topic_,
			               static_cast<int64_t>(last_index_));
		return false;
	}

	double fractionRead() const override
	{
		return file_size_ ? static_cast<double>(file_pos_) / file_size_ : 1.0;
	}

   private:
	struct Item
	{
		uint32_t conn = 0;
		int64_t time_ns = 0;
	};
	std::ifstream in_;
	uint64_t file_size_ = 0, file_pos_ = 0;
	std::vector<uint8_t> record_, chunk_;
	size_t chunk_pos_ = 0;
	bool in_chunk_ = false;
	uint64_t chunk_index_ = 0;
	std::string scan_error_, damage_;
	bool scan_done_ = false;
	std::vector<TopicInfo> topics_;
	std::map<uint32_t, size_t> topic_of_conn_;
	std::map<std::string, size_t> topic_by_name_;
	std::set<std::string> selected_;
	std::map<std::string, uint64_t> per_topic_;
	std::string last_topic_;
	uint64_t last_index_ = 0;

	void rewind()
	{
		in_ = std::ifstream(path_, std::ios::binary);
		if (!in_) throw BagError("cannot open bag '" + path_ + "'");
		in_.seekg(0, std::ios::end);
		file_size_ = static_cast<uint64_t>(in_.tellg());
		in_.seekg(static_cast<std::streamoff>(kMagicLen));
		file_pos_ = kMagicLen;
		in_chunk_ = false;
		chunk_index_ = 0;
		scan_error_.clear();
		per_topic_.clear();
	}

	void registerConnection(const Fields& hdr, const uint8_t* data,
	                        uint32_t len)
	{
		const uint32_t conn = fieldU32(hdr, "conn");
		if (topic_of_conn_.count(conn)) return;
		Fields ch;
		if (!parseFields(data, len, ch)) return;
		const std::string topic =
		    hdr.count("topic") ? hdr.at("topic") : ch["topic"];
		auto it = topic_by_name_.find(topic);
		if (it == topic_by_name_.end())
		{
			if (scan_done_) return;  // pass 2 knows every connection
			it = topic_by_name_.emplace(topic, topics_.size()).first;
			topics_.push_back(makeTopic(topic, ch["type"], ch["md5sum"]));
		}
		topic_of_conn_[conn] = it->second;
	}

	/** Reads one top-level record into record_; false at EOF or damage. */
	bool readTopRecord(Fields& fields, const uint8_t*& data, uint32_t& len)
	{
		if (file_pos_ == file_size_) return false;
		uint32_t hl = 0;
		auto fail = [&](const std::string& why)
		{
			scan_error_ = "bag truncated or damaged at byte " +
			              std::to_string(file_pos_) + " of " +
			              std::to_string(file_size_) + ": " + why;
			return false;
		};
		if (file_size_ - file_pos_ < 4) return fail("incomplete record header");
		in_.read(reinterpret_cast<char*>(&hl), 4);
		if (hl > file_size_ - file_pos_ - 4) return fail("record header cut");
		record_.resize(hl);
		in_.read(reinterpret_cast<char*>(record_.data()), hl);
		if (!parseFields(record_.data(), hl, fields))
			return fail("malformed record header");
		uint32_t dl = 0;
		if (file_size_ - file_pos_ - 4 - hl < 4) return fail("record cut");
		in_.read(reinterpret_cast<char*>(&dl), 4);
		if (dl > file_size_ - file_pos_ - 8 - hl)
			return fail("record data cut (chunk #" +
			            std::to_string(chunk_index_) + ")");
		const size_t hdr_bytes = record_.size();
		record_.resize(hdr_bytes + dl);
		in_.read(reinterpret_cast<char*>(record_.data() + hdr_bytes), dl);
		if (!in_) return fail("read error");
		file_pos_ += 8 + hl + dl;
		data = record_.data() + hdr_bytes;
		len = dl;
		return true;
	}

	bool decompress(const Fields& f, const uint8_t* data, uint32_t len)
	{
		const std::string comp =
		    f.count("compression") ? f.at("compression") : "none";
		const uint32_t size = fieldU32(f, "size");
		if (comp == "none")
		{
			chunk_.assign(data, data + len);
			return true;
		}
		if (size == UINT32_MAX) return false;
		chunk_.resize(size);
		if (comp == "lz4")
		{
			unsigned int out = size;
			const int rc = roslz4_buffToBuffDecompress(
			    const_cast<char*>(reinterpret_cast<const char*>(data)), len,
			    reinterpret_cast<char*>(chunk_.data()), &out);
			return rc == ROSLZ4_OK && out == size;
		}
		if (comp == "bz2")
		{
			unsigned int out = size;
			const int rc = BZ2_bzBuffToBuffDecompress(
			    reinterpret_cast<char*>(chunk_.data()), &out,
			    const_cast<char*>(reinterpret_cast<const char*>(data)), len, 0,
			    0);
			return rc == BZ_OK && out == size;
		}
		scan_error_ = "unknown chunk compression '" + comp + "'";
		return false;
	}

	/** Next message record (any topic); fills out.data/size if given. */
	bool step(Item& item, BagMessage* out)
	{
		for (;;)
		{
			if (in_chunk_)
			{
				Fields f;
				const uint8_t* d = nullptr;
				uint32_t dl = 0;
				if (chunk_pos_ < chunk_.size() &&
				    takeRecord(chunk_.data(), chunk_.size(), chunk_pos_, f, d,
				               dl))
				{
					const std::string op = f.count("op") ? f["op"] : "";
					if (op == "\x07")
						registerConnection(f, d, dl);
					else if (op == "\x02")
					{
						item.conn = fieldU32(f, "conn");
						item.time_ns = fieldTimeNs(f);
						if (!topic_of_conn_.count(item.conn)) continue;
						if (out)
						{
							out->data = d;
							out->size = dl;
						}
						return true;
					}
					continue;
				}
				if (chunk_pos_ < chunk_.size())
				{
					scan_error_ = "malformed record inside chunk #" +
					              std::to_string(chunk_index_);
					return false;
				}
				in_chunk_ = false;
			}
			Fields f;
			const uint8_t* d = nullptr;
			uint32_t dl = 0;
			if (!readTopRecord(f, d, dl)) return false;
			const std::string op = f.count("op") ? f["op"] : "";
			if (op == "\x05")
			{
				chunk_index_++;
				if (!decompress(f, d, dl))
				{
					if (scan_error_.empty())
						scan_error_ = "cannot decompress chunk #" +
						              std::to_string(chunk_index_) +
						              " at byte " + std::to_string(file_pos_);
					return false;
				}
				chunk_pos_ = 0;
				in_chunk_ = true;
			}
			else if (op == "\x07")
				registerConnection(f, d, dl);
		}
	}
};

}  // namespace

std::unique_ptr<BagReader> openRos1Bag(const std::string& path)
{
	{
		std::ifstream f(path, std::ios::binary);
		if (!f) throw BagError("cannot open bag '" + path + "'");
		char magic[kMagicLen] = {};
		f.read(magic, kMagicLen);
		if (std::string(magic, kMagicLen) != kMagic)
			throw BagError(
			    "'" + path +
			    "' is not a ROS 1 bag of format 2.0 (it does not start with "
			    "\"#ROSBAG V2.0\"); ROS 2 bags are folders with metadata.yaml");
	}
	auto bag = std::make_unique<rosbag::Bag>();
	try
	{
		bag->open(path, rosbag::bagmode::Read);
		return std::make_unique<Ros1IndexedReader>(path, std::move(bag));
	}
	catch (const rosbag::BagException& e)
	{
		FS_LOG_WARN("bag '" << path << "' cannot be opened through its index ("
		                    << e.what()
		                    << "): reading it record by record instead "
		                       "(was the recording interrupted?)");
	}
	return std::make_unique<Ros1SequentialReader>(path);
}

}  // namespace forest_slam::ingest
