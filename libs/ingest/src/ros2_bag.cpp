// ROS 2 bags (rosbag2, sqlite3 storage): metadata.yaml lists the .db3 files;
// each has tables topics(id, name, type, serialization_format) and
// messages(topic_id, timestamp, data). Messages stream from one SQL cursor
// per file ordered by timestamp, so memory stays flat.
#include <forest_slam/ingest/bag_reader.h>

#include <mrpt/containers/yaml.h>
#include <sqlite3.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>

namespace fs = std::filesystem;

namespace forest_slam::ingest
{
namespace
{
struct Db
{
	sqlite3* db = nullptr;
	Db() = default;
	Db(const Db&) = delete;
	Db& operator=(const Db&) = delete;
	~Db()
	{
		if (db) sqlite3_close(db);
	}
};

struct Stmt
{
	sqlite3_stmt* s = nullptr;
	Stmt() = default;
	Stmt(const Stmt&) = delete;
	Stmt& operator=(const Stmt&) = delete;
	~Stmt() { reset(); }
	void reset()
	{
		if (s) sqlite3_finalize(s);
		s = nullptr;
	}
};

std::string sqlError(sqlite3* db)
{
	return db ? sqlite3_errmsg(db) : "?";
}

/** "x_10.db3" after "x_9.db3": compare the trailing number numerically. */
bool naturalLess(const fs::path& a, const fs::path& b)
{
	auto split = [](const std::string& s)
	{
		size_t e = s.size();
		size_t i = e;
		while (i > 0 && std::isdigit(static_cast<unsigned char>(s[i - 1]))) i--;
		const long n = i < e ? std::stol(s.substr(i, e - i)) : -1;
		return std::make_pair(s.substr(0, i), n);
	};
	return split(a.stem().string()) < split(b.stem().string());
}

class Ros2Reader : public BagReader
{
   public:
	explicit Ros2Reader(const std::string& path) : BagReader(path)
	{
		fs::path p(path);
		if (fs::is_regular_file(p) && p.filename() == "metadata.yaml")
			p = p.parent_path();
		if (fs::is_regular_file(p))
			files_.push_back(p.string());
		else if (fs::is_directory(p))
			listFiles(p);
		else
			throw BagError("bag '" + path + "' does not exist");
		if (files_.empty())
			throw BagError("ROS 2 bag '" + path + "' contains no .db3 file");
		scanTopics();
	}

	BagFormat format() const override { return BagFormat::Ros2; }
	const std::vector<TopicInfo>& topics() const override { return topics_; }

	void select(const std::vector<std::string>& names) override
	{
		selected_ = std::set<std::string>(names.begin(), names.end());
		total_ = 0;
		for (const auto& n : names)
			if (const auto* t = findTopic(n)) total_ += t->count;
	}

	bool next(BagMessage& out) override
	{
		for (;;)
		{
			if (!stmt_.s)
			{
				if (file_idx_ >= files_.size()) return false;
				openCursor(files_[file_idx_++]);
				if (!stmt_.s) continue;
			}
			const int rc = sqlite3_step(stmt_.s);
			if (rc == SQLITE_DONE)
			{
				stmt_.reset();
				db_ = std::make_unique<Db>();
				continue;
			}
			if (rc != SQLITE_ROW)
			{
				std::string where;
				if (!last_topic_.empty())
					where = " after message #" + std::to_string(last_index_) +
					        " of " + last_topic_;
				throw BagError("bag file '" + current_file_ + "' is damaged" +
				                   where + ": " + sqlError(db_->db),
				               last_topic_, static_cast<int64_t>(last_index_));
			}
			const int64_t tid = sqlite3_column_int64(stmt_.s, 0);
			auto it = topic_of_id_.find(tid);
			if (it == topic_of_id_.end()) continue;
			const TopicInfo& t = topics_[it->second];
			out.topic = &t;
			out.index = per_topic_[t.name]++;
			out.time_ns = sqlite3_column_int64(stmt_.s, 1);
			out.data =
			    static_cast<const uint8_t*>(sqlite3_column_blob(stmt_.s, 2));
			out.size = static_cast<size_t>(sqlite3_column_bytes(stmt_.s, 2));
			out.wire = Wire::Cdr;
			last_topic_ = t.name;
			last_index_ = out.index;
			consumed_++;
			return true;
		}
	}

	double fractionRead() const override
	{
		return total_ ? static_cast<double>(consumed_) / total_ : 1.0;
	}

   private:
	std::vector<std::string> files_;
	std::vector<TopicInfo> topics_;
	std::set<std::string> selected_;
	std::unique_ptr<Db> db_ = std::make_unique<Db>();
	Stmt stmt_;
	std::string current_file_;
	size_t file_idx_ = 0;
	std::map<int64_t, size_t> topic_of_id_;  ///< of the current file
	std::map<std::string, uint64_t> per_topic_;
	std::string last_topic_;
	uint64_t last_index_ = 0, total_ = 0, consumed_ = 0;

	void listFiles(const fs::path& dir)
	{
		const fs::path meta = dir / "metadata.yaml";
		if (fs::exists(meta))
		{
			mrpt::containers::yaml y;
			try
			{
				y = mrpt::containers::yaml::FromFile(meta.string());
			}
			catch (const std::exception& e)
			{
				throw BagError("cannot parse '" + meta.string() +
				               "': " + e.what());
			}
			if (!y.has("rosbag2_bagfile_information"))
				throw BagError("'" + meta.string() +
				               "' has no rosbag2_bagfile_information");
			const auto info = y["rosbag2_bagfile_information"];
			auto str = [&](const char* k)
			{
				return info.has(k) && info[k].isScalar()
				           ? info[k].as<std::string>()
				           : std::string();
			};
			const std::string storage = str("storage_identifier");
			if (!storage.empty() && storage != "sqlite3")
				throw BagError("ROS 2 bag '" + dir.string() +
				               "' uses storage '" + storage +
				               "'; only sqlite3 (.db3) is supported");
			const std::string comp = str("compression_format");
			if (!comp.empty())
				throw BagError("ROS 2 bag '" + dir.string() +
				               "' is compressed (" + comp +
				               "); decompress it first (ros2 bag convert)");
			if (info.has("relative_file_paths"))
				for (const auto& f : info["relative_file_paths"].asSequence())
					files_.push_back((dir / f.as<std::string>()).string());
			for (const auto& f : files_)
				if (!fs::exists(f))
					throw BagError("ROS 2 bag '" + dir.string() + "': file '" +
					               f + "' listed in metadata.yaml is missing");
			if (!files_.empty()) return;
		}
		std::vector<fs::path> dbs;
		for (const auto& e : fs::directory_iterator(dir))
			if (e.path().extension() == ".db3") dbs.push_back(e.path());
		std::sort(dbs.begin(), dbs.end(), naturalLess);
		for (const auto& d : dbs) files_.push_back(d.string());
	}

	void openDb(const std::string& file, Db& db)
	{
		// immutable=1: the bag may sit on a read-only disk, and sqlite must
		// not try to create -wal/-shm files or take locks.
		const std::string uri = "file:" + file + "?immutable=1";
		if (sqlite3_open_v2(uri.c_str(), &db.db,
		                    SQLITE_OPEN_READONLY | SQLITE_OPEN_URI,
		                    nullptr) != SQLITE_OK)
			throw BagError("cannot open '" + file + "': " + sqlError(db.db));
	}

	void scanTopics()
	{
		std::map<std::string, size_t> by_name;
		for (const auto& file : files_)
		{
			Db db;
			openDb(file, db);
			Stmt st;
			if (sqlite3_prepare_v2(
			        db.db,
			        "SELECT t.name, t.type, t.serialization_format, "
			        "COUNT(m.id), MIN(m.timestamp), MAX(m.timestamp) FROM "
			        "topics t "
			        "LEFT JOIN messages m ON m.topic_id = t.id GROUP BY t.id",
			        -1, &st.s, nullptr) != SQLITE_OK)
				throw BagError(
				    "'" + file +
				    "' is not a rosbag2 sqlite3 file: " + sqlError(db.db));
			int rc;
			while ((rc = sqlite3_step(st.s)) == SQLITE_ROW)
			{
				auto text = [&](int c)
				{
					const auto* p = sqlite3_column_text(st.s, c);
					return p ? std::string(reinterpret_cast<const char*>(p))
					         : std::string();
				};
				const std::string name = text(0);
				auto it = by_name.find(name);
				if (it == by_name.end())
				{
					TopicInfo t;
					t.name = name;
					t.type = text(1);
					t.kind = kindOfType(t.type);
					t.serialization = text(2);
					it = by_name.emplace(name, topics_.size()).first;
					topics_.push_back(t);
				}
				TopicInfo& t = topics_[it->second];
				const uint64_t n = sqlite3_column_int64(st.s, 3);
				if (n == 0) continue;
				const int64_t a = sqlite3_column_int64(st.s, 4);
				const int64_t b = sqlite3_column_int64(st.s, 5);
				t.first_ns = t.count ? std::min(t.first_ns, a) : a;
				t.last_ns = t.count ? std::max(t.last_ns, b) : b;
				t.count += n;
			}
			if (rc != SQLITE_DONE)
				throw BagError("cannot list topics of '" + file +
				               "': " + sqlError(db.db));
		}
	}

	void openCursor(const std::string& file)
	{
		current_file_ = file;
		stmt_.reset();
		db_ = std::make_unique<Db>();
		openDb(file, *db_);
		topic_of_id_.clear();
		{
			Stmt st;
			if (sqlite3_prepare_v2(db_->db, "SELECT id, name FROM topics", -1,
			                       &st.s, nullptr) != SQLITE_OK)
				throw BagError("cannot read topics of '" + file +
				               "': " + sqlError(db_->db));
			while (sqlite3_step(st.s) == SQLITE_ROW)
			{
				const auto* p = sqlite3_column_text(st.s, 1);
				const std::string name =
				    p ? reinterpret_cast<const char*>(p) : "";
				if (!selected_.count(name)) continue;
				for (size_t i = 0; i < topics_.size(); i++)
					if (topics_[i].name == name)
						topic_of_id_[sqlite3_column_int64(st.s, 0)] = i;
			}
		}
		if (topic_of_id_.empty()) return;
		std::string ids;
		for (const auto& [id, idx] : topic_of_id_)
			ids += (ids.empty() ? "" : ",") + std::to_string(id);
		const std::string sql =
		    "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN "
		    "(" +
		    ids + ") ORDER BY timestamp, id";
		if (sqlite3_prepare_v2(db_->db, sql.c_str(), -1, &stmt_.s, nullptr) !=
		    SQLITE_OK)
			throw BagError("cannot read messages of '" + file +
			               "': " + sqlError(db_->db));
	}
};
}  // namespace

std::unique_ptr<BagReader> openRos2Bag(const std::string& path)
{
	return std::make_unique<Ros2Reader>(path);
}

double TopicInfo::rateHz() const
{
	if (count < 2 || last_ns <= first_ns) return 0;
	return (count - 1) / ((last_ns - first_ns) * 1e-9);
}

const TopicInfo* BagReader::findTopic(const std::string& name) const
{
	for (const auto& t : topics())
		if (t.name == name) return &t;
	return nullptr;
}

std::unique_ptr<BagReader> BagReader::open(const std::string& path)
{
	const fs::path p(path);
	if (!fs::exists(p)) throw BagError("bag '" + path + "' does not exist");
	if (fs::is_directory(p) || p.extension() == ".db3" ||
	    p.filename() == "metadata.yaml")
		return openRos2Bag(path);
	return openRos1Bag(path);
}

}  // namespace forest_slam::ingest
