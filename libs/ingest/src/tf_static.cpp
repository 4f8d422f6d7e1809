#include <forest_slam/ingest/tf_static.h>

#include <mrpt/math/CQuaternion.h>
#include <mrpt/poses/CPose3DQuat.h>

namespace forest_slam::ingest
{
std::string canonicalFrame(const std::string& f)
{
	return !f.empty() && f[0] == '/' ? f.substr(1) : f;
}

void StaticTransforms::add(const TfMsg& msg)
{
	for (const auto& t : msg.transforms)
	{
		const auto& q = t.rotation_xyzw;
		mrpt::math::CQuaternionDouble quat(q[3], q[0], q[1], q[2]);
		quat.normalize();
		const mrpt::poses::CPose3DQuat pq(t.translation[0], t.translation[1],
		                                  t.translation[2], quat);
		parent_[canonicalFrame(t.child_frame_id)] = {
		    canonicalFrame(t.header.frame_id), mrpt::poses::CPose3D(pq)};
	}
}

bool StaticTransforms::lookup(const std::string& frame, const std::string& base,
                              mrpt::poses::CPose3D& out) const
{
	const std::string b = canonicalFrame(base);
	std::string f = canonicalFrame(frame);
	mrpt::poses::CPose3D acc;  // frame in f's ancestor, built leaf upwards
	for (size_t hops = 0; hops <= parent_.size(); hops++)
	{
		if (f == b)
		{
			out = acc;
			return true;
		}
		auto it = parent_.find(f);
		if (it == parent_.end()) return false;
		acc = it->second.child_in_parent + acc;
		f = it->second.parent;
	}
	return false;  // a cycle
}

std::string StaticTransforms::describe() const
{
	std::string s;
	for (const auto& [child, e] : parent_)
		s += (s.empty() ? "" : ", ") + child + " -> " + e.parent;
	return s;
}

}  // namespace forest_slam::ingest
