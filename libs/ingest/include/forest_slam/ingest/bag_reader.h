#pragma once
// Streams the messages of a ROS 1 bag (.bag, through librosbag-storage) or a
// ROS 2 bag (folder with metadata.yaml + sqlite3 .db3 files) in time order,
// as raw serialized bytes, one message in memory at a time.
#include <forest_slam/ingest/messages.h>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace forest_slam::ingest
{
/** Damage or misuse of a bag: names the bag and, when known, the topic and
 * the 0-based index of the message within that topic. */
class BagError : public std::runtime_error
{
   public:
	BagError(const std::string& msg, std::string topic = "",
	         int64_t message_index = -1)
	    : std::runtime_error(msg),
	      topic(std::move(topic)),
	      message_index(message_index)
	{
	}
	std::string topic;
	int64_t message_index;
};

enum class BagFormat
{
	Ros1,
	Ros2
};

struct TopicInfo
{
	std::string name;
	std::string type;  ///< as recorded, e.g. "sensor_msgs/msg/Imu"
	MsgKind kind = MsgKind::Unknown;
	std::string md5;                     ///< ROS 1 only
	std::string serialization = "ros1";  ///< "ros1", "cdr", ...
	uint64_t count = 0;
	int64_t first_ns = 0, last_ns = 0;  ///< record (receive) times
	/** Mean message rate [Hz] over the topic's time span (0 if < 2). */
	double rateHz() const;
};

struct BagMessage
{
	const TopicInfo* topic = nullptr;
	uint64_t index = 0;             ///< 0-based within its topic
	int64_t time_ns = 0;            ///< record time (not the header stamp)
	const uint8_t* data = nullptr;  ///< valid until the next call to next()
	size_t size = 0;
	Wire wire = Wire::Ros1;
};

class BagReader
{
   public:
	/** Opens `path`: a directory or a .db3/.yaml path is a ROS 2 bag, anything
	 * else must start with "#ROSBAG V2.0". A ROS 1 bag without its index
	 * (recording interrupted, file truncated) is read sequentially up to the
	 * damage, with a warning. Throws BagError. */
	static std::unique_ptr<BagReader> open(const std::string& path);
	virtual ~BagReader() = default;

	virtual BagFormat format() const = 0;
	/** All topics with counts and time spans. */
	virtual const std::vector<TopicInfo>& topics() const = 0;
	const TopicInfo* findTopic(const std::string& name) const;
	/** Restricts iteration to these topics (call before the first next()). */
	virtual void select(const std::vector<std::string>& topic_names) = 0;
	/** Next selected message in time order; false at a clean end. Throws
	 * BagError (with topic and index) if the bag is damaged. */
	virtual bool next(BagMessage& out) = 0;
	/** Fraction of the selected messages (or bytes) consumed, [0,1]. */
	virtual double fractionRead() const = 0;
	/** Non-empty when the bag is known to be damaged (e.g. truncated): the
	 * messages before the damage are still delivered, then next() throws. */
	virtual std::string damage() const { return {}; }
	const std::string& path() const { return path_; }

   protected:
	explicit BagReader(std::string path) : path_(std::move(path)) {}
	std::string path_;
};

std::unique_ptr<BagReader> openRos1Bag(const std::string& path);
std::unique_ptr<BagReader> openRos2Bag(const std::string& path);

}  // namespace forest_slam::ingest
