#include "frontend_scorer.h"

#include <forest_slam/odometry/lidar_odometry.h>

#include <forest_slam/io/rawlog_reader.h>
#include <forest_slam/io/tum.h>
#include <mrpt/obs/CObservationRotatingScan.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <unordered_map>

namespace forest_slam::frontend_eval
{
const char* gtLabelName(uint16_t label)
{
	static const char* names[] = {"none",  "ground", "stem",
	                              "crown", "shrub",  "structure"};
	return label < kLabelCount ? names[label] : "?";
}

namespace
{
double ratio(uint64_t a, uint64_t b)
{
	return b ? double(a) / double(b) : 0.0;
}
double median(std::vector<double> v)
{
	if (v.empty()) return 0;
	std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
	return v[v.size() / 2];
}
double mean(const std::vector<double>& v)
{
	double s = 0;
	for (double x : v) s += x;
	return v.empty() ? 0 : s / v.size();
}
using Clock = std::chrono::steady_clock;
double msBetween(Clock::time_point a, Clock::time_point b)
{
	return std::chrono::duration<double, std::milli>(b - a).count();
}
}  // namespace

double FrontEndScore::groundPrecision() const
{
	return ratio(tp, tp + fp);
}
double FrontEndScore::groundRecall() const
{
	return ratio(tp, tp + fn);
}
double FrontEndScore::mixingRate() const
{
	return ratio(mixed_clusters, tree_clusters);
}
double FrontEndScore::mixingPointRate() const
{
	return ratio(mixed_cluster_points, tree_cluster_points);
}
double FrontEndScore::stemMixingRate() const
{
	return ratio(mixed_stem_clusters, stem_clusters);
}
double FrontEndScore::edgeOnTreeFraction() const
{
	return ratio(edges_by_label[kStem] + edges_by_label[kCrown], edges);
}

void FrontEndScore::add(const FrontEndScore& o)
{
	scans += o.scans;
	tp += o.tp, fp += o.fp, fn += o.fn, tn += o.tn;
	beyond_radius += o.beyond_radius;
	for (int l = 0; l < kLabelCount; l++)
	{
		fp_by_label[l] += o.fp_by_label[l];
		edges_by_label[l] += o.edges_by_label[l];
	}
	tree_clusters += o.tree_clusters, mixed_clusters += o.mixed_clusters;
	tree_cluster_points += o.tree_cluster_points;
	mixed_cluster_points += o.mixed_cluster_points;
	stem_clusters += o.stem_clusters;
	mixed_stem_clusters += o.mixed_stem_clusters;
	clusters += o.clusters;
	edges += o.edges, planar += o.planar;
	for (auto [dst, src] : {std::pair{&ground_ms, &o.ground_ms},
	                        {&cluster_ms, &o.cluster_ms},
	                        {&features_ms, &o.features_ms}})
		dst->insert(dst->end(), src->begin(), src->end());
}

std::string FrontEndScore::summary() const
{
	char buf[2048];
	std::string s;
	std::snprintf(buf, sizeof(buf),
	              "scans %zu\n"
	              "ground    precision %6.2f %%  recall %6.2f %%  (TP %llu FP "
	              "%llu FN %llu; %llu points beyond radius)\n",
	              scans, 100 * groundPrecision(), 100 * groundRecall(),
	              (unsigned long long)tp, (unsigned long long)fp,
	              (unsigned long long)fn, (unsigned long long)beyond_radius);
	s += buf;
	s += "          false ground by GT label:";
	for (int l = kStem; l < kLabelCount; l++)
	{
		std::snprintf(buf, sizeof(buf), " %s %llu", gtLabelName(l),
		              (unsigned long long)fp_by_label[l]);
		s += buf;
	}
	std::snprintf(
	    buf, sizeof(buf),
	    "\ncluster   tree mixing %5.2f %% of %llu tree clusters (%5.2f %% of "
	    "their points), stem mixing %5.2f %% of %llu; %.1f clusters/scan\n"
	    "features  edges on stems/branches %6.2f %% of %llu (%.1f "
	    "edges/scan, %.1f planar/scan); edges by GT label:",
	    100 * mixingRate(), (unsigned long long)tree_clusters,
	    100 * mixingPointRate(), 100 * stemMixingRate(),
	    (unsigned long long)stem_clusters, scans ? double(clusters) / scans : 0,
	    100 * edgeOnTreeFraction(), (unsigned long long)edges,
	    scans ? double(edges) / scans : 0, scans ? double(planar) / scans : 0);
	s += buf;
	for (int l = kGround; l < kLabelCount; l++)
	{
		std::snprintf(buf, sizeof(buf), " %s %.1f%%", gtLabelName(l),
		              100 * ratio(edges_by_label[l], edges));
		s += buf;
	}
	std::snprintf(buf, sizeof(buf),
	              "\ntime/scan ground %.3f ms  cluster %.3f ms  features %.3f "
	              "ms (median; means %.3f %.3f %.3f)\n",
	              median(ground_ms), median(cluster_ms), median(features_ms),
	              mean(ground_ms), mean(cluster_ms), mean(features_ms));
	s += buf;
	return s;
}

FrontEndScorer::FrontEndScorer(const FrontEndOptions& o,
                               const core::Trajectory& gt)
    : o_(o), gt_(gt), lattice_(o.ground)
{
}

bool FrontEndScorer::addScan(const core::ScanPoints& scan)
{
	const auto* label = scan.layer("gt_label");
	const auto* tree = scan.layer("gt_tree");
	if (!label || !tree)
		throw std::runtime_error(
		    "front-end scorer: scan without gt_label/gt_tree layers");
	Eigen::Isometry3d T0;
	if (!core::interpolatePose(gt_, scan.stamp_s, T0, 1e-3)) return false;
	const Eigen::Isometry3d T0inv = T0.inverse();

	// Deskew with the GT pose of every firing column: map frame for the
	// ground lattice, frame of the first firing for clusters and features.
	std::unordered_map<uint32_t, Eigen::Isometry3f> column_T;
	std::vector<features::FeatureInputPoint> fin;
	std::vector<Eigen::Vector3f> in_map;
	std::vector<uint32_t> src;  // input point of each fin entry
	fin.reserve(scan.points.size());
	for (uint32_t i = 0; i < scan.points.size(); i++)
	{
		const auto& p = scan.points[i];
		const Eigen::Vector3f raw(p.x, p.y, p.z);
		if (!raw.allFinite()) continue;
		auto it = column_T.find(p.column);
		if (it == column_T.end())
		{
			Eigen::Isometry3d Ti;
			if (!core::interpolatePose(gt_, scan.stamp_s + p.t_s, Ti, 1e-3))
				return false;
			it = column_T.emplace(p.column, Ti.cast<float>()).first;
		}
		in_map.push_back(it->second * raw);
		features::FeatureInputPoint f;
		f.xyz = (T0inv.cast<float>() * in_map.back());
		f.ring = p.ring;
		f.column = p.column;
		fin.push_back(f);
		src.push_back(i);
	}
	FrontEndScore s;
	s.scans = 1;

	auto t0 = Clock::now();
	const auto ground = lattice_.labelScan(in_map, T0.translation());
	auto t1 = Clock::now();
	const size_t n_clusters =
	    odometry::labelGroundAndCluster(fin, ground, o_.cluster);
	auto t2 = Clock::now();
	const auto feats = features::extractFeatures(fin, o_.features);
	auto t3 = Clock::now();
	s.ground_ms.push_back(msBetween(t0, t1));
	s.cluster_ms.push_back(msBetween(t1, t2));
	s.features_ms.push_back(msBetween(t2, t3));

	// Ground.
	const double r2 = o_.ground.radius_m * o_.ground.radius_m;
	const Eigen::Vector3d c = T0.translation();
	for (size_t i = 0; i < fin.size(); i++)
	{
		const double dx = in_map[i].x() - c.x(), dy = in_map[i].y() - c.y();
		if (dx * dx + dy * dy > r2)
		{
			s.beyond_radius++;
			continue;
		}
		const uint16_t l = (*label)[src[i]];
		const bool truth = l == kGround, said = ground[i] != 0;
		if (said && truth)
			s.tp++;
		else if (said)
		{
			s.fp++;
			s.fp_by_label[std::min<uint16_t>(l, kLabelCount - 1)]++;
		}
		else if (truth)
			s.fn++;
		else
			s.tn++;
	}

	// Clusters: the GT trees each one holds.
	struct Members
	{
		std::vector<uint16_t> trees, stem_trees;
		uint32_t tree_points = 0;
	};
	std::vector<Members> members(n_clusters);
	for (size_t k = 0; k < fin.size(); k++)
	{
		const int32_t id = fin[k].ground ? -1 : fin[k].cluster;
		if (id < 0) continue;
		const uint32_t i = src[k];
		const uint16_t t = (*tree)[i];
		if (t == 0) continue;
		auto& m = members[id];
		m.tree_points++;
		if (std::find(m.trees.begin(), m.trees.end(), t) == m.trees.end())
			m.trees.push_back(t);
		if ((*label)[i] == kStem &&
		    std::find(m.stem_trees.begin(), m.stem_trees.end(), t) ==
		        m.stem_trees.end())
			m.stem_trees.push_back(t);
	}
	s.clusters = n_clusters;
	for (const auto& m : members)
	{
		if (!m.trees.empty())
		{
			s.tree_clusters++;
			s.tree_cluster_points += m.tree_points;
			if (m.trees.size() > 1)
			{
				s.mixed_clusters++;
				s.mixed_cluster_points += m.tree_points;
			}
		}
		if (!m.stem_trees.empty())
		{
			s.stem_clusters++;
			if (m.stem_trees.size() > 1) s.mixed_stem_clusters++;
		}
	}

	// Features.
	s.edges = feats.edges.size();
	s.planar = feats.planar.size();
	for (auto i : feats.edges)
		s.edges_by_label[std::min<uint16_t>((*label)[src[i]],
		                                    kLabelCount - 1)]++;
	score_.add(s);
	last_.in_map = std::move(in_map);
	last_.points = std::move(fin);
	last_.gt_label.resize(src.size());
	last_.gt_tree.resize(src.size());
	for (size_t i = 0; i < src.size(); i++)
	{
		last_.gt_label[i] = (*label)[src[i]];
		last_.gt_tree[i] = (*tree)[src[i]];
	}
	last_.ground = ground;
	last_.feats = feats;
	last_.sensor_in_map = c;
	return true;
}

FrontEndScore scoreRawlog(const std::string& rawlog, const std::string& gt_tum,
                          const FrontEndOptions& o, size_t first_scan,
                          size_t max_scans)
{
	const auto gt = io::readTum(gt_tum);
	FrontEndScorer scorer(o, gt);
	io::RawlogReader r(rawlog);
	size_t k = 0;
	while (auto obs = r.next())
	{
		auto scan =
		    std::dynamic_pointer_cast<mrpt::obs::CObservationRotatingScan>(obs);
		if (!scan) continue;
		if (k++ < first_scan) continue;
		if (k - first_scan > max_scans) break;
		scorer.addScan(core::unpackRotatingScan(*scan));
	}
	return scorer.score();
}

}  // namespace forest_slam::frontend_eval
