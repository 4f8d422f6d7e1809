#pragma once
// Static extrinsics from /tf_static: the chain of transforms from a sensor's
// frame up to the vehicle (base) frame, composed into the sensorPose MRPT
// observations carry.
#include <forest_slam/ingest/messages.h>

#include <mrpt/poses/CPose3D.h>

#include <map>
#include <string>

namespace forest_slam::ingest
{
class StaticTransforms
{
   public:
	/** Later messages replace earlier transforms of the same child frame. */
	void add(const TfMsg& msg);
	bool empty() const { return parent_.empty(); }
	size_t size() const { return parent_.size(); }
	/** Pose of `frame` in `base` (frames compared without a leading '/').
	 * False if the chain from `frame` does not reach `base`. */
	bool lookup(const std::string& frame, const std::string& base,
	            mrpt::poses::CPose3D& out) const;
	/** "a -> b, c -> b" for messages. */
	std::string describe() const;

   private:
	struct Edge
	{
		std::string parent;
		mrpt::poses::CPose3D child_in_parent;
	};
	std::map<std::string, Edge> parent_;  ///< keyed by child frame
};

/** Frame id without the leading '/' ROS 1 sometimes keeps. */
std::string canonicalFrame(const std::string& f);

}  // namespace forest_slam::ingest
