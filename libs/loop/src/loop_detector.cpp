#include <forest_slam/core/parallel_for.h>
#include <forest_slam/loop/loop_detector.h>

#include <algorithm>
#include <cmath>

namespace forest_slam::loop
{
std::vector<size_t> loopCandidates(const std::vector<Keyframe>& kfs,
                                   const Poses& poses, size_t current,
                                   const LoopOptions& o)
{
	const auto& cur = kfs[current];
	const Eigen::Vector3d pc = poses[current].translation();
	std::vector<std::pair<double, size_t>> near;
	for (size_t j = 0; j < current; j++)
	{
		const double travel = cur.travelled_m - kfs[j].travelled_m;
		if (travel < o.min_travel_m) break;  // travelled_m grows with j
		const double radius =
		    o.search_radius_m + o.search_drift_fraction * travel;
		const Eigen::Vector3d d = poses[j].translation() - pc;
		if (d.head<2>().norm() > radius || std::abs(d.z()) > radius) continue;
		near.emplace_back(d.norm(), j);
	}
	std::sort(near.begin(), near.end());
	// Keep candidates from different places along the path (not several
	// neighbours of one keyframe, which would verify the same overlap).
	std::vector<size_t> out;
	for (const auto& [d, j] : near)
	{
		bool close = false;
		for (size_t k : out)
			if (std::abs(kfs[k].travelled_m - kfs[j].travelled_m) <
			    2 * o.submap_keyframes * o.keyframe_distance_m)
				close = true;
		if (close) continue;
		out.push_back(j);
		if (out.size() >= static_cast<size_t>(o.max_candidates)) break;
	}
	return out;
}

PlaceDescriptor keyframeDescriptor(const std::vector<Keyframe>& kfs,
                                   const Poses& poses, size_t id,
                                   const LoopOptions& o)
{
	const size_t m = static_cast<size_t>(o.descriptor_keyframes);
	auto pts =
	    submapCloud(kfs, poses, id >= m ? id - m : 0, id, id, o.cloud_voxel_m);
	const Eigen::Matrix3f L =
	    levellingRotation(poses[id].linear()).cast<float>();
	for (auto& p : pts) p = L * p;
	PlaceDescriptorOptions d;
	d.rings = o.descriptor_rings;
	d.sectors = o.descriptor_sectors;
	d.radius_m = o.descriptor_radius_m;
	return PlaceDescriptor(pts, d);
}

std::vector<DescriptorCandidate> descriptorCandidates(
    const std::vector<Keyframe>& kfs, const Poses& poses,
    const std::vector<PlaceDescriptor>& descriptors, size_t current,
    const std::vector<size_t>& geometric, const LoopOptions& o)
{
	std::vector<DescriptorCandidate> out;
	const auto& dc = descriptors.at(current);
	if (dc.empty()) return out;
	// Retrieval: the nearest ring keys (yaw-invariant).
	std::vector<std::pair<float, size_t>> keys;
	for (size_t j = 0; j < current; j++)
	{
		if (kfs[current].travelled_m - kfs[j].travelled_m < o.min_travel_m)
			break;  // travelled_m grows with j
		if (descriptors[j].empty()) continue;
		keys.emplace_back((descriptors[j].ringKey() - dc.ringKey()).norm(), j);
	}
	const size_t n =
	    std::min(keys.size(), static_cast<size_t>(o.descriptor_retrieval));
	std::partial_sort(keys.begin(), keys.begin() + n, keys.end());
	std::vector<DescriptorCandidate> all;
	for (size_t i = 0; i < n; i++)
	{
		DescriptorCandidate c;
		c.from = keys[i].second;
		c.match = matchDescriptors(descriptors[c.from], dc);
		all.push_back(c);
	}
	auto better = [](const DescriptorCandidate& a, const DescriptorCandidate& b)
	{
		return a.match.distance < b.match.distance ||
		       (a.match.distance == b.match.distance && a.from < b.from);
	};
	std::sort(all.begin(), all.end(), better);
	const double sep = 2 * o.submap_keyframes * o.keyframe_distance_m;
	auto near = [&](size_t a, size_t b)
	{ return std::abs(kfs[a].travelled_m - kfs[b].travelled_m) < sep; };
	// Distinctiveness: another place (elsewhere along the path and in the
	// estimate: not an earlier visit of the same place already joined to
	// it) that matches nearly as well makes the match ambiguous (regular
	// plantations): no descriptor candidate then.
	if (!all.empty())
	{
		const auto& b = all.front();
		for (size_t i = 1; i < all.size(); i++)
		{
			const auto& c = all[i];
			const bool elsewhere =
			    !near(b.from, c.from) &&
			    (poses[b.from].translation() - poses[c.from].translation())
			            .head<2>()
			            .norm() > 2 * o.icp_start_distance_m;
			if (elsewhere && b.match.distance >
			                     o.descriptor_distinct_ratio * c.match.distance)
				return out;
			if (elsewhere) break;  // the best other place is distinct enough
		}
	}
	std::vector<DescriptorCandidate> matches;
	for (const auto& c : all)
		if (c.match.distance <= o.descriptor_max_distance) matches.push_back(c);
	// Different places along the path, and not the hypothesis of a
	// geometric candidate again.
	const double yaw_cur = yawOf(poses[current].linear());
	for (const auto& c : matches)
	{
		double dyaw = yaw_cur - yawOf(poses[c.from].linear()) - c.match.yaw_rad;
		dyaw = std::remainder(dyaw, 2 * M_PI);
		const bool estimate_agrees =
		    std::abs(dyaw) < 2 * 2 * M_PI / o.descriptor_sectors &&
		    (poses[c.from].translation() - poses[current].translation())
		            .head<2>()
		            .norm() < 2 * o.icp_start_distance_m;
		bool close = false;
		for (size_t k : geometric)
			close = close || (estimate_agrees && near(k, c.from));
		for (const auto& k : out) close = close || near(k.from, c.from);
		if (close) continue;
		out.push_back(c);
		if (out.size() >= static_cast<size_t>(o.descriptor_candidates)) break;
	}
	return out;
}

std::vector<Eigen::Vector3f> submapCloud(const std::vector<Keyframe>& kfs,
                                         const Poses& poses, size_t first,
                                         size_t last, size_t ref,
                                         double voxel_m)
{
	std::vector<Eigen::Vector3f> pts;
	const Eigen::Isometry3d ref_inv = poses[ref].inverse();
	for (size_t i = first; i <= last && i < kfs.size(); i++)
	{
		const Eigen::Isometry3f T = (ref_inv * poses[i]).cast<float>();
		for (const auto& p : kfs[i].cloud) pts.push_back(T * p);
	}
	return voxelFilter(pts, voxel_m, 1e9);
}

std::vector<Eigen::Vector3f> thinEvenly(const std::vector<Eigen::Vector3f>& pts,
                                        size_t max_points)
{
	if (max_points == 0 || pts.size() <= max_points) return pts;
	std::vector<Eigen::Vector3f> out;
	out.reserve(max_points);
	for (size_t i = 0; i < max_points; i++)
		out.push_back(pts[i * pts.size() / max_points]);
	return out;
}

namespace
{
/** Rotation vector and translation of A^-1 B. */
Eigen::Matrix<double, 6, 1> difference(const Eigen::Isometry3d& A,
                                       const Eigen::Isometry3d& B)
{
	const Eigen::Isometry3d D = A.inverse() * B;
	const Eigen::AngleAxisd aa(D.linear());
	Eigen::Matrix<double, 6, 1> v;
	v.head<3>() = D.translation();
	v.tail<3>() = aa.angle() * aa.axis();
	return v;
}
}  // namespace

Closure verifyClosure(const std::vector<Keyframe>& kfs, const Poses& poses,
                      size_t from, size_t to, const LoopOptions& o,
                      const DescriptorMatch* seed)
{
	Closure c;
	c.from = from;
	c.to = to;
	c.descriptor = seed != nullptr;
	if (seed) c.descriptor_distance = seed->distance;
	c.travelled_m = kfs[to].travelled_m - kfs[from].travelled_m;
	const size_t m = static_cast<size_t>(o.submap_keyframes);
	const size_t t_first = from >= m ? from - m : 0;
	const size_t t_last = std::min(from + m, to - 1);
	const size_t s_first = to >= m ? to - m : 0;
	// Both submaps from the same resolution: the target with normals.
	IcpTarget target(withNormals(
	    submapCloud(kfs, poses, t_first, t_last, from, o.cloud_voxel_m), 10,
	    0.3, o.verify_threads));
	auto source = submapCloud(kfs, poses, std::max(s_first, t_last + 1), to, to,
	                          o.cloud_voxel_m);
	if (target.size() < 200 || source.size() < 200)
	{
		c.reason = "few_points";
		return c;
	}
	source = thinEvenly(source, static_cast<size_t>(o.icp_max_points));
	IcpOptions io;
	io.iterations = o.icp_iterations;
	io.start_distance_m = o.icp_start_distance_m;
	io.final_distance_m = o.icp_final_distance_m;
	// The estimate's relative pose; a descriptor candidate starts instead
	// from its match: both frames levelled, the descriptor's yaw between
	// them, the same place (no offset).
	const Eigen::Isometry3d estimate = poses[from].inverse() * poses[to];
	const Eigen::Matrix3d L_to = levellingRotation(poses[to].linear());
	Eigen::Isometry3d guess = estimate;
	if (seed)
	{
		guess = Eigen::Isometry3d::Identity();
		guess.linear() =
		    levellingRotation(poses[from].linear()).transpose() *
		    Eigen::AngleAxisd(seed->yaw_rad, Eigen::Vector3d::UnitZ()) * L_to;
	}
	const IcpResult r = target.align(source, guess, io);
	c.T = r.T;
	c.overlap = r.overlap;
	c.rmse_m = r.rmse_m;
	// The correction the closure asks of the estimate (also the
	// consistency gate's input below).
	const auto to_estimate = difference(estimate, r.T);
	c.error_m = to_estimate.head<3>().norm();
	c.error_deg = to_estimate.tail<3>().norm() * 180 / M_PI;
	if (!r.converged)
	{
		c.reason = "not_converged";
		return c;
	}
	if (r.overlap < o.min_overlap)
	{
		c.reason = "overlap";
		return c;
	}
	if (r.rmse_m > o.max_rmse_m)
	{
		c.reason = "rmse";
		return c;
	}
	const auto& ev = r.information_eigenvalues;
	// A match adds at most 1 to a direction's information (unit normal;
	// rotations scaled to a 10 m lever): the weakest direction must be
	// constrained by a fair share of the matches (not a corridor).
	if (!(ev[5] > 0) || ev[0] < o.min_information_ratio * r.matches)
	{
		c.reason = "degenerate";
		return c;
	}
	// Consistency: the correction against the current estimate must be a
	// drift the odometry can have made over the distance travelled.
	const double st = o.loop_sigma_t_m + o.odom_sigma_t_per_m * c.travelled_m;
	const double sr =
	    (o.loop_sigma_r_deg + o.odom_sigma_r_deg_per_m * c.travelled_m) * M_PI /
	    180;
	if (!seed)
	{
		c.chi2 = to_estimate.head<3>().squaredNorm() / (st * st) +
		         to_estimate.tail<3>().squaredNorm() / (sr * sr);
	}
	else
	{
		// A descriptor candidate is there because the drift may be beyond
		// what the odometry model expects: its horizontal position and yaw
		// are not gated by that model. Instead ICP must have stayed near
		// the descriptor's match (two independent measurements agree: the
		// yaw within two sectors, the offset within twice the first
		// correspondence gate) ...
		const auto ds = difference(guess, r.T);
		if (ds.tail<3>().norm() > 2 * 2 * M_PI / o.descriptor_sectors ||
		    ds.head<3>().norm() > 2 * o.icp_start_distance_m)
		{
			c.reason = "descriptor_mismatch";
			return c;
		}
		// ... and what gravity keeps observable, the height and the tilt,
		// is gated by the drift model as before.
		const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
		const Eigen::Vector3d up_closure =
		    (poses[from].linear() * r.T.linear()).transpose() * up;
		const Eigen::Vector3d up_estimate = poses[to].linear().transpose() * up;
		const double tilt =
		    std::acos(std::clamp(up_closure.dot(up_estimate), -1.0, 1.0));
		const double dz =
		    (poses[from].linear() * r.T.translation()).z() -
		    (poses[to].translation() - poses[from].translation()).z();
		c.chi2 = dz * dz / (st * st) + tilt * tilt / (sr * sr);
	}
	if (c.chi2 > o.consistency_chi2)
	{
		c.reason = "inconsistent";
		return c;
	}
	// Uniqueness: from guesses displaced horizontally (in the candidate's
	// frame, where the ground is level), ICP must come back to the same
	// alignment or find a clearly worse one. These re-runs only have to
	// find another alignment, not refine one: half the source points, and
	// the alternatives are compared with the same half at r.T.
	const auto half =
	    thinEvenly(source, std::max<size_t>(200, source.size() / 2));
	const IcpResult ref = target.evaluate(half, r.T, io);
	const double shift = std::max(1.0, 1.5 * o.icp_start_distance_m);
	// A descriptor candidate also from its match turned by 90, 180 and 270
	// degrees about the vertical (rows of a plantation look alike from
	// several directions; its yaw is not checked by the estimate).
	const int guesses = seed ? 7 : 4;
	// The re-runs are independent: shared out among the verifying threads,
	// then judged in order, as one after the other would (every guess is
	// run, also after an ambiguous one: a rejected candidate's few).
	std::vector<IcpResult> alts(static_cast<size_t>(guesses));
	core::parallelFor(
	    alts.size(), o.verify_threads, 1,
	    [&](size_t k)
	    {
		    const double a = static_cast<double>(k) * M_PI / 2;
		    Eigen::Isometry3d g = r.T;
		    if (k < 4)
			    g.translation() +=
			        shift * Eigen::Vector3d(std::cos(a), std::sin(a), 0);
		    else
			    g.linear() =
			        r.T.linear() * L_to.transpose() *
			        Eigen::AngleAxisd(static_cast<double>(k - 3) * M_PI / 2,
			                          Eigen::Vector3d::UnitZ()) *
			        L_to;
		    alts[k] = target.align(half, g, io);
	    });
	for (const IcpResult& alt : alts)
	{
		if (!alt.converged) continue;
		const auto dd = difference(r.T, alt.T);
		const bool other =
		    dd.head<3>().norm() > 0.3 || dd.tail<3>().norm() > 1.0 * M_PI / 180;
		if (other && alt.overlap > 0.9 * ref.overlap &&
		    alt.rmse_m < 1.2 * ref.rmse_m)
		{
			c.reason = "ambiguous";
			return c;
		}
	}
	c.accepted = true;
	return c;
}

}  // namespace forest_slam::loop
