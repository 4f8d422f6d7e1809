#include <forest_slam/trees/outlier_filter.h>
#include <forest_slam/trees/stem_clustering.h>
#include <forest_slam/trees/stem_detector.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

namespace forest_slam::trees
{
namespace
{
constexpr size_t kSectionFitPoints = 300;
constexpr size_t kRingSearchPoints = 400;
/** findRing's samples at least, however good the first ones were. */
constexpr int kMinRingSamples = 30;
// The solid-ring DBH fit (fitSolidRing): for stems whose circle has an
// RMSE above kSolidMinRmseM (foliage in the ring; a clean ring under 2.5 cm
// range noise stays below 3 cm) seen over at least kSolidMinArcDeg, taken
// if it shrinks the radius by more than kSolidMinShrinkM.
constexpr double kSolidMinRmseM = 0.035;
constexpr double kSolidMinArcDeg = 240;
constexpr double kSolidMinShrinkM = 0.005;
constexpr int kSolidRingIterations = 500;
// The silhouette estimate (silhouetteRadius) counts the points within this
// beyond the fitted circle: 1.6 sigma of the range noise (2.5 cm). On the
// forest-sim runs (ground-truth and SLAM poses) 3-4 cm kept the clutter out
// best: DBH MAPE of the blended stems' runs lowest, 6 and 8 cm worse.
constexpr double kSilhouetteReachM = 0.04;
/** Scatter of a section's centre about the stem's axis [m]: a chain's axis
 * extrapolated beyond its own span is uncertain by about this times the
 * distance over the span (linking, below). */
constexpr double kSectionCentreSigmaM = 0.01;

CircleFitOptions fitOptions(const TreeOptions& o, double rmin, double rmax)
{
	CircleFitOptions f;
	f.min_radius_m = rmin;
	f.max_radius_m = rmax;
	f.ransac_iterations = o.ransac_iterations;
	f.ransac_inlier_m = o.ransac_inlier_m;
	f.seed = o.seed;
	f.arc_bin_deg = o.arc_bin_deg;
	return f;
}

/** Least-squares line v = a + b·h; returns false if degenerate. */
bool fitLine(const std::vector<double>& h, const std::vector<double>& v,
             double& a, double& b)
{
	const size_t n = h.size();
	if (n < 2) return false;
	double mh = 0, mv = 0;
	for (size_t i = 0; i < n; i++) mh += h[i], mv += v[i];
	mh /= n, mv /= n;
	double shh = 0, shv = 0;
	for (size_t i = 0; i < n; i++)
		shh += (h[i] - mh) * (h[i] - mh), shv += (h[i] - mh) * (v[i] - mv);
	if (shh <= 0) return false;
	b = shv / shh;
	a = mv - b * mh;
	return true;
}

struct Chain
{
	std::vector<StemSection> s;
	// Axis x(h) = ax + bx h, y(h) = ay + by h; radius r(h) = ar + br h.
	double ax = 0, bx = 0, ay = 0, by = 0, ar = 0, br = 0;
	bool fitted = false;

	void fit()
	{
		std::vector<double> h, x, y, r;
		for (const auto& q : s)
			h.push_back(q.height_m), x.push_back(q.centre.x()),
			    y.push_back(q.centre.y()), r.push_back(q.radius_m);
		fitted = fitLine(h, x, ax, bx) && fitLine(h, y, ay, by) &&
		         fitLine(h, r, ar, br);
		if (!fitted)
		{
			ax = x.back(), ay = y.back(), ar = r.back(), bx = by = br = 0;
		}
	}
	Eigen::Vector2d at(double h) const { return {ax + bx * h, ay + by * h}; }
	double radiusAt(double h) const { return ar + br * h; }
	double medianRadius() const { return median(&StemSection::radius_m); }
	double medianArcDeg() const { return median(&StemSection::arc_deg); }
	double median(double StemSection::*field) const
	{
		std::vector<double> v;
		for (const auto& q : s) v.push_back(q.*field);
		std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
		return v[v.size() / 2];
	}
};
}  // namespace

/** RANSAC for a hollow ring inside a cluster of clutter: the second and
 * third samples are taken near the first (the ring is a small part of the
 * cluster), candidates are scored by the points on the ring minus twice
 * those inside it (a stem's slice is hollow, a shrub's is not), the best is
 * refined on its own points. Returns the fit on the ring's points
 * (n_inliers of them), or !ok. */
namespace
{
CircleFitResult findRing(const Points2D& p, const TreeOptions& o, double rmin,
                         double rmax)
{
	CircleFitResult res;
	if (p.size() < size_t(o.min_slice_points)) return res;
	std::mt19937 rng(o.seed);
	std::uniform_int_distribution<size_t> pick(0, p.size() - 1);
	const double tol = o.ransac_inlier_m;
	// On squared distances (no root per point). A candidate stops being
	// scored once it cannot beat `beat` any more, even with every point left
	// on its ring (the score it returns then is `beat`): most samples are
	// through clutter and stop early.
	const long n_pts = long(p.size());
	auto score = [&](const Circle& c, Points2D* ring,
	                 long beat = std::numeric_limits<long>::min())
	{
		long on = 0, inside = 0;
		const double inner = c.radius_m - std::max(3 * tol, 0.3 * c.radius_m);
		const double inner2 = inner > 0 ? inner * inner : -1;
		auto sq = [](double v) { return v * v; };
		const double band_lo2 = sq(std::max(0.0, c.radius_m - 2 * tol)),
		             band_hi2 = sq(c.radius_m + 2 * tol),
		             on_lo2 = sq(std::max(0.0, c.radius_m - tol)),
		             on_hi2 = sq(c.radius_m + tol);
		for (long i = 0; i < n_pts; i++)
		{
			const double d2 = (p[size_t(i)] - c.centre).squaredNorm();
			if (d2 >= band_lo2 && d2 <= band_hi2)
			{
				on += d2 >= on_lo2 && d2 <= on_hi2;
				if (ring) ring->push_back(p[size_t(i)]);
			}
			else if (d2 < inner2)
				inside++;
			if (on - 2 * inside + (n_pts - 1 - i) <= beat)
				return std::make_pair(beat, inside);
		}
		return std::make_pair(on - 2 * inside, inside);
	};
	Circle best;
	long best_score = 0;
	// Stops once a sample all on the ring is likely drawn; the ring's share
	// of the cluster is a lower bound on the chance (the second and third
	// samples are drawn near the first).
	int needed = o.ransac_iterations;
	for (int it = 0; it < needed; it++)
	{
		const size_t a = pick(rng);
		size_t bc[2] = {a, a};
		for (size_t& x : bc)
			for (int t = 0; t < 20; t++)
			{
				const size_t y = pick(rng);
				if (y != a && (p[y] - p[a]).norm() <= 2 * rmax)
				{
					x = y;
					break;
				}
			}
		if (bc[0] == a || bc[1] == a || bc[0] == bc[1]) continue;
		Circle cand;
		if (!circleThrough3(p[a], p[bc[0]], p[bc[1]], cand) ||
		    cand.radius_m < rmin || cand.radius_m > rmax)
			continue;
		const auto [sc, inside] = score(cand, nullptr, best_score);
		if (sc > best_score)
		{
			best_score = sc, best = cand;
			needed = ransacIterationsNeeded(
			    double(sc + 2 * inside) / double(p.size()), kMinRingSamples,
			    o.ransac_iterations);
		}
	}
	if (best_score < o.min_slice_points) return res;
	Points2D ring;
	score(best, &ring);
	Circle c = best;
	if (!refineCircleGeometric(ring, c) || c.radius_m < rmin ||
	    c.radius_m > rmax)
		return res;
	Points2D ring2;
	const auto [sc, inside] = score(c, &ring2);
	if (sc < o.min_slice_points || double(inside) > 0.15 * ring2.size())
		return res;
	CircleFitOptions f;
	f.min_radius_m = rmin;
	f.max_radius_m = rmax;
	f.arc_bin_deg = o.arc_bin_deg;
	return evaluateCircle(ring2, c, f);
}
}  // namespace

std::vector<StemSection> findSliceSections(const Points2D& xy, int slice_index,
                                           double height_m,
                                           const TreeOptions& o,
                                           size_t* n_clusters)
{
	std::vector<StemSection> out;
	// The objects of a slice are told apart at the scale of link_distance_m:
	// cluster one point per link_distance_m/4 square (the slice of a dense
	// map holds tens of points per such square; the neighbourhood search
	// over all of them was most of the detection time), then give every
	// point its square's cluster, so the circle fits see all points.
	std::vector<uint32_t> cell_of;
	const Points2D coarse = thinToCells(xy, 0.25 * o.link_distance_m, &cell_of);
	const auto leaf =
	    sliceKMeansLeaves(coarse, o.kmeans_branching, o.kmeans_leaf_points);
	const auto coarse_clusters =
	    mergeLeavesByNeighbourhood(coarse, leaf, o.link_distance_m);
	std::vector<uint32_t> cluster_of(coarse.size());
	for (size_t c = 0; c < coarse_clusters.size(); c++)
		for (size_t i : coarse_clusters[c]) cluster_of[i] = uint32_t(c);
	std::vector<std::vector<size_t>> clusters(coarse_clusters.size());
	for (size_t i = 0; i < xy.size(); i++)
		clusters[cluster_of[cell_of[i]]].push_back(i);
	if (n_clusters) *n_clusters = clusters.size();
	const double rmin = 0.5 * o.min_dbh_m * 0.7, rmax = 0.5 * o.max_dbh_m * 1.2;
	for (const auto& c : clusters)
	{
		if (c.size() < size_t(o.min_slice_points)) continue;
		Eigen::Vector2d lo = xy[c[0]], hi = xy[c[0]];
		// A section only has to be recognised and located (the DBH is fitted
		// later on all points): an evenly strided subset of at most
		// kSectionFitPoints keeps the fit cost bounded on dense maps.
		const size_t stride =
		    (c.size() + kSectionFitPoints - 1) / kSectionFitPoints;
		Points2D pts;
		pts.reserve(c.size() / stride + 1);
		for (size_t j = 0; j < c.size(); j++)
		{
			const auto& q = xy[c[j]];
			lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
			if (j % stride == 0) pts.push_back(q);
		}
		// Walls and hedges: wider than any stem we accept.
		const bool narrow = (hi - lo).maxCoeff() <= 1.5 * o.max_dbh_m;
		auto f = narrow ? fitCircleRobust(pts, fitOptions(o, rmin, rmax))
		                : CircleFitResult{};
		auto plausible = [&](const CircleFitResult& g, size_t n)
		{
			const double r = g.circle.radius_m;
			return g.ok && r >= 0.5 * o.min_dbh_m * 0.8 &&
			       r <= 0.5 * o.max_dbh_m &&
			       g.rmse_m <= o.section_max_rmse_m + o.section_rmse_rel * r &&
			       g.arc_coverage_deg >= o.section_min_arc_deg &&
			       double(g.n_inliers) >=
			           o.section_min_inlier_ratio * double(n);
		};
		if (!plausible(f, pts.size()))
		{
			// (A stem joined with clutter makes a big cluster: small ones
			// are not searched, they cost most of the time.)
			if (!o.section_ring_search ||
			    c.size() < 3 * size_t(o.min_slice_points))
				continue;
			// Clutter touching a stem (low spruce branches, a shrub at its
			// foot) joins it into one cluster that fails as a whole: look
			// for a hollow ring inside it.
			const size_t s2 =
			    (c.size() + kRingSearchPoints - 1) / kRingSearchPoints;
			Points2D all;
			for (size_t j = 0; j < c.size(); j += s2) all.push_back(xy[c[j]]);
			f = findRing(all, o, rmin, rmax);
			if (!f.ok || !plausible(f, f.n_inliers)) continue;
		}
		const double r = f.circle.radius_m;
		StemSection s;
		s.slice = slice_index;
		s.height_m = height_m;
		s.centre = f.circle.centre;
		s.radius_m = r;
		s.rmse_m = f.rmse_m;
		s.arc_deg = f.arc_coverage_deg;
		s.n_points = f.n_inliers;
		out.push_back(s);
	}
	return out;
}

CircleFitResult fitDbhSegments(const Points2D& p, const Points2D& dir,
                               const std::vector<uint32_t>& segment,
                               const Circle& c0, double gate_m,
                               const TreeOptions& o, double rmin, double rmax)
{
	CircleFitResult res;
	if (p.size() != dir.size() || p.size() != segment.size()) return res;
	const size_t min_seg = std::max<size_t>(3, size_t(o.min_dbh_points) / 2);
	Circle c = c0;
	Points2D shift(p.size(), Eigen::Vector2d::Zero());
	Points2D q, qd, q_shift;
	for (int round = 0; round < 2; round++)
	{
		// Points within the gate of their segment's (shifted) circle.
		std::vector<size_t> idx;
		for (size_t i = 0; i < p.size(); i++)
			if (std::abs((p[i] - c.centre - shift[i]).norm() - c.radius_m) <=
			    gate_m)
				idx.push_back(i);
		std::vector<uint32_t> ids;
		for (size_t i : idx) ids.push_back(segment[i]);
		std::sort(ids.begin(), ids.end());
		std::vector<uint32_t> keep;  // segments with enough points
		for (size_t a = 0; a < ids.size();)
		{
			size_t b = a;
			while (b < ids.size() && ids[b] == ids[a]) b++;
			if (b - a >= min_seg) keep.push_back(ids[a]);
			a = b;
		}
		if (keep.empty()) return res;
		q.clear(), qd.clear();
		std::vector<uint32_t> qs;
		std::vector<size_t> qi;
		for (size_t i : idx)
			if (std::binary_search(keep.begin(), keep.end(), segment[i]))
				q.push_back(p[i]), qd.push_back(dir[i]),
				    qs.push_back(segment[i]), qi.push_back(i);
		Circle cn = c;
		if (!refineCircleSegments(q, qd, qs, o.dbh_segment_shift_m, cn,
		                          &q_shift))
			return res;
		c = cn;
		// Every point gets its segment's shift (0 for dropped segments).
		std::vector<std::pair<uint32_t, Eigen::Vector2d>> by_seg;
		for (size_t j = 0; j < qi.size(); j++)
			if (by_seg.empty() || by_seg.back().first != qs[j])
				by_seg.emplace_back(qs[j], q_shift[j]);
		std::sort(by_seg.begin(), by_seg.end(),
		          [](const auto& a, const auto& b)
		          { return a.first < b.first; });
		for (size_t i = 0; i < p.size(); i++)
		{
			const auto it = std::lower_bound(
			    by_seg.begin(), by_seg.end(), segment[i],
			    [](const auto& a, uint32_t v) { return a.first < v; });
			shift[i] = it != by_seg.end() && it->first == segment[i]
			               ? it->second
			               : Eigen::Vector2d::Zero();
		}
		// Second round: gate at 4 robust scales of the aligned points.
		std::vector<double> r;
		for (size_t j = 0; j < q.size(); j++)
			r.push_back(
			    std::abs((q[j] - c.centre - q_shift[j]).norm() - c.radius_m));
		std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
		gate_m = std::max(4 * 1.4826 * r[r.size() / 2], 2 * o.ransac_inlier_m);
	}
	if (c.radius_m < rmin || c.radius_m > rmax ||
	    std::abs(c.radius_m - c0.radius_m) > 0.25 * c0.radius_m ||
	    (c.centre - c0.centre).norm() > 0.5 * c0.radius_m)
		return res;
	Points2D aligned;
	for (size_t j = 0; j < q.size(); j++) aligned.push_back(q[j] - q_shift[j]);
	CircleFitOptions f;
	f.min_radius_m = rmin;
	f.max_radius_m = rmax;
	f.arc_bin_deg = o.arc_bin_deg;
	return evaluateCircle(aligned, c, f);
}

std::vector<DetectedTree> detectTrees(
    const std::vector<Eigen::Vector3d>& pts, const TerrainModel& terrain,
    const TreeOptions& o, TreeDetectionStats* stats,
    const std::vector<Eigen::Vector3f>* view_dirs,
    const SegmentedPoints* segments, const std::vector<float>* point_times)
{
	if (view_dirs && view_dirs->size() != pts.size())
		throw std::invalid_argument(
		    "detectTrees: view_dirs must hold one direction per point");
	if (point_times && point_times->size() != pts.size())
		throw std::invalid_argument(
		    "detectTrees: point_times must hold one time per point");
	if (segments && (segments->dirs.size() != segments->pts.size() ||
	                 segments->segment.size() != segments->pts.size() ||
	                 (!segments->range_class.empty() &&
	                  segments->range_class.size() != segments->pts.size())))
		throw std::invalid_argument(
		    "detectTrees: segments must hold a direction and a segment per "
		    "point");
	TreeDetectionStats st;
	std::vector<double> hag(pts.size());
	for (size_t i = 0; i < pts.size(); i++)
		hag[i] = terrain.heightAboveGround(pts[i]);

	// 2. Stem sections in every slice.
	const int n_slices =
	    int(std::floor((o.slice_max_m - o.slice_min_m) / o.slice_step_m +
	                   1e-9)) +
	    1;
	std::vector<std::vector<StemSection>> by_slice(n_slices);
	{
		std::vector<Points2D> slice_xy(n_slices);
		const double half = 0.5 * o.slice_thickness_m;
		for (size_t i = 0; i < pts.size(); i++)
		{
			const double u = (hag[i] - o.slice_min_m) / o.slice_step_m;
			const int s = int(std::lround(u));
			if (s < 0 || s >= n_slices) continue;
			if (std::abs(hag[i] - (o.slice_min_m + s * o.slice_step_m)) > half)
				continue;
			slice_xy[s].emplace_back(pts[i].x(), pts[i].y());
		}
		for (int s = 0; s < n_slices; s++)
		{
			if (o.slice_cell_m > 0)
				slice_xy[s] = thinToCells(slice_xy[s], o.slice_cell_m);
			size_t nc = 0;
			by_slice[s] = findSliceSections(
			    slice_xy[s], s, o.slice_min_m + s * o.slice_step_m, o, &nc);
			st.slice_clusters += nc;
			st.sections += by_slice[s].size();
		}
		st.slices = size_t(n_slices);
	}

	// 3. Link sections upwards into chains.
	const double tan_lean = std::tan(o.max_lean_deg * M_PI / 180);
	std::vector<Chain> chains;
	for (int s = 0; s < n_slices; s++)
	{
		std::vector<char> taken(chains.size(), 0);
		for (const auto& sec : by_slice[s])
		{
			int best = -1;
			double best_d = 1e9;
			for (size_t c = 0; c < chains.size(); c++)
			{
				if (taken[c]) continue;
				const auto& last = chains[c].s.back();
				const int gap = s - last.slice - 1;
				if (gap < 0 || gap > o.max_slice_gap) continue;
				const double dh = sec.height_m - last.height_m;
				const double ratio = sec.radius_m / last.radius_m;
				if (ratio > o.max_radius_ratio ||
				    ratio < 1 / o.max_radius_ratio)
					continue;
				double d, tol;
				if (chains[c].s.size() >= 2)
				{
					d = (chains[c].at(sec.height_m) - sec.centre).norm();
					tol = o.max_centre_step_m * std::max(dh, 0.5);
					// Two sections 0.25 m apart give a lean uncertain by
					// several cm per metre: across a gap of missing slices
					// its extrapolation misses the stem's next section (the
					// 58-minute run's GT 860: 10.5 cm off at 0.75 m above
					// a two-section chain, its stem then split in two
					// chains too short to count).
					const double span =
					    last.height_m - chains[c].s.front().height_m;
					if (span > 0 && dh > span)
						tol +=
						    std::sqrt(2.0) * kSectionCentreSigmaM * dh / span;
				}
				else
				{
					d = (last.centre - sec.centre).norm();
					tol =
					    o.max_centre_step_m * std::max(dh, 0.5) + tan_lean * dh;
				}
				if (d <= tol && d < best_d) best_d = d, best = int(c);
			}
			if (best >= 0)
			{
				chains[best].s.push_back(sec);
				chains[best].fit();
				taken[best] = 1;
			}
			else
			{
				chains.emplace_back();
				chains.back().s.push_back(sec);
				chains.back().fit();
				taken.push_back(1);
			}
		}
	}
	st.chains = chains.size();

	// Validate chains: enough slices, plausible lean, taper and straightness.
	std::vector<Chain> stems;
	for (auto& c : chains)
	{
		if (int(c.s.size()) < o.min_slices)
		{
			st.rejected_short++;
			continue;
		}
		c.fit();
		double ss = 0;
		for (const auto& q : c.s)
			ss += (c.at(q.height_m) - q.centre).squaredNorm();
		const double axis_rmse = std::sqrt(ss / c.s.size());
		const double lean = std::atan(std::hypot(c.bx, c.by));
		if (!c.fitted || lean > o.max_lean_deg * M_PI / 180 ||
		    std::abs(c.br) > o.max_taper_m_per_m ||
		    axis_rmse > o.max_axis_rmse_m)
		{
			st.rejected_shape++;
			continue;
		}
		stems.push_back(c);
	}
	// Duplicates (two chains on one stem, e.g. split by a gap): keep the
	// better-confirmed one.
	std::sort(stems.begin(), stems.end(),
	          [](const Chain& a, const Chain& b)
	          { return a.s.size() > b.s.size(); });
	std::vector<Chain> unique;
	for (const auto& c : stems)
	{
		bool dup = false;
		for (const auto& u : unique)
			if ((u.at(o.dbh_height_m) - c.at(o.dbh_height_m)).norm() <
			    std::max(u.medianRadius(), c.medianRadius()))
				dup = true;
		if (dup)
			st.rejected_duplicate++;
		else
			unique.push_back(c);
	}

	// 4. DBH, points, height per stem.
	std::vector<DetectedTree> trees;
	// Points by 1 m cell, so each stem visits its neighbourhood only.
	Eigen::Vector2d lo_xy(1e300, 1e300), hi_xy(-1e300, -1e300);
	for (const auto& p : pts)
		lo_xy = lo_xy.cwiseMin(p.head<2>()),
		hi_xy = hi_xy.cwiseMax(p.head<2>());
	const double cell = 1.0;
	const int gx = pts.empty() ? 0 : int((hi_xy.x() - lo_xy.x()) / cell) + 1;
	const int gy = pts.empty() ? 0 : int((hi_xy.y() - lo_xy.y()) / cell) + 1;
	std::vector<std::vector<uint32_t>> grid(size_t(gx) * gy);
	for (size_t i = 0; i < pts.size(); i++)
		grid[int((pts[i].x() - lo_xy.x()) / cell) +
		     gx * int((pts[i].y() - lo_xy.y()) / cell)]
		    .push_back(uint32_t(i));
	// The segmented breast-height points by 1 m cell, likewise.
	Eigen::Vector2d s_lo(1e300, 1e300), s_hi(-1e300, -1e300);
	int sgx = 0, sgy = 0;
	std::vector<std::vector<uint32_t>> s_grid;
	std::vector<double> s_hag;
	if (segments && o.dbh_segment_scans > 0 && !segments->pts.empty())
	{
		for (const auto& p : segments->pts)
			s_lo = s_lo.cwiseMin(p.head<2>()),
			s_hi = s_hi.cwiseMax(p.head<2>());
		sgx = int((s_hi.x() - s_lo.x()) / cell) + 1;
		sgy = int((s_hi.y() - s_lo.y()) / cell) + 1;
		s_grid.resize(size_t(sgx) * sgy);
		s_hag.resize(segments->pts.size());
		for (size_t i = 0; i < segments->pts.size(); i++)
		{
			const auto& p = segments->pts[i];
			s_hag[i] = terrain.heightAboveGround(p);
			s_grid[int((p.x() - s_lo.x()) / cell) +
			       sgx * int((p.y() - s_lo.y()) / cell)]
			    .push_back(uint32_t(i));
		}
	}
	std::vector<uint32_t> near_idx;
	for (const auto& c : unique)
	{
		const double r_est = c.medianRadius();
		const Eigen::Vector3d axis =
		    Eigen::Vector3d(c.bx, c.by, 1.0).normalized();
		const Eigen::Vector2d xy0 = c.at(o.dbh_height_m);
		const Eigen::Vector3d p0(
		    xy0.x(), xy0.y(),
		    terrain.heightAt(xy0.x(), xy0.y()) + o.dbh_height_m);
		Eigen::Vector3d e1 = axis.cross(Eigen::Vector3d::UnitY()).normalized();
		const Eigen::Vector3d e2 = axis.cross(e1).normalized();
		e1 = e2.cross(axis).normalized();

		Points2D band, band_dir;     // band_dir: unit, or 0 if unknown
		std::vector<double> band_t;  // point times (0 if unknown)
		size_t n_points = 0;
		std::vector<double> column_h;
		const double lo_h = o.slice_min_m - 0.5 * o.slice_thickness_m;
		const double hi_h = o.slice_max_m + 0.5 * o.slice_thickness_m;
		// Every point below can matter only within `reach` of the axis.
		const double reach =
		    std::max({o.top_search_radius_m, 1.6 * r_est + 0.1,
		              std::max(c.radiusAt(lo_h), c.radiusAt(hi_h)) + 0.05});
		const Eigen::Vector2d a_lo = c.at(lo_h), a_hi = c.at(hi_h);
		const Eigen::Vector2d b_lo = a_lo.cwiseMin(a_hi).array() - reach,
		                      b_hi = a_lo.cwiseMax(a_hi).array() + reach;
		near_idx.clear();
		for (int iy = std::max(0, int((b_lo.y() - lo_xy.y()) / cell));
		     iy <= std::min(gy - 1, int((b_hi.y() - lo_xy.y()) / cell)); iy++)
			for (int ix = std::max(0, int((b_lo.x() - lo_xy.x()) / cell));
			     ix <= std::min(gx - 1, int((b_hi.x() - lo_xy.x()) / cell));
			     ix++)
				near_idx.insert(near_idx.end(), grid[ix + gx * iy].begin(),
				                grid[ix + gx * iy].end());
		std::sort(near_idx.begin(), near_idx.end());  // input order
		for (const uint32_t i : near_idx)
		{
			const double h = hag[i];
			if (h < lo_h) continue;
			const Eigen::Vector2d axis_xy = c.at(std::min(h, hi_h));
			const double dist = (pts[i].head<2>() - axis_xy).norm();
			if (h <= hi_h && dist <= c.radiusAt(h) + 0.05) n_points++;
			if (h > hi_h && dist <= o.top_search_radius_m)
				column_h.push_back(h);
			if (std::abs(h - o.dbh_height_m) <= o.dbh_band_half_m &&
			    dist <= 1.6 * r_est + 0.1)
			{
				const Eigen::Vector3d d = pts[i] - p0;
				band.emplace_back(d.dot(e1), d.dot(e2));
				Eigen::Vector2d v = Eigen::Vector2d::Zero();
				if (view_dirs)
				{
					const Eigen::Vector3d w = (*view_dirs)[i].cast<double>();
					v = Eigen::Vector2d(w.dot(e1), w.dot(e2));
					// Mean of unit vectors: short if the voxel was seen from
					// very different sides; nearly vertical rays carry no
					// horizontal range information either.
					v = v.norm() > 0.5 ? Eigen::Vector2d(v.normalized())
					                   : Eigen::Vector2d::Zero();
				}
				band_dir.push_back(v);
				band_t.push_back(point_times ? (*point_times)[i] : 0.0);
			}
		}
		if (n_points < size_t(o.min_tree_points))
		{
			st.rejected_points++;
			continue;
		}
		DetectedTree t;
		t.axis = axis;
		t.lean_deg = std::acos(std::clamp(axis.z(), -1.0, 1.0)) * 180 / M_PI;
		t.sections = c.s;
		auto& rec = t.record;
		rec.n_points = uint32_t(n_points);
		rec.n_slices = uint16_t(c.s.size());

		Points2D kept;
		for (size_t i : statisticalOutlierFilter(band, o.sor_k, o.sor_omega))
			kept.push_back(band[i]);
		const auto fo = fitOptions(
		    o, 0.5 * r_est, std::min(1.5 * r_est, 0.5 * o.max_dbh_m * 1.2));
		auto f = kept.size() >= size_t(o.min_dbh_points)
		             ? fitCircleRobust(kept, fo)
		             : CircleFitResult{};
		// The SOR circle seeds a final geometric fit on every band point
		// within a symmetric residual gate: SOR's density criterion drops the
		// outer half of the noise band more than the inner one (inside a
		// circle the same noise is packed denser), which would shrink the
		// DBH by about sigma^2/r.
		if (f.ok)
		{
			const double gate = std::max(4 * f.scale_m, 2 * o.ransac_inlier_m);
			Points2D near, near_dir;
			std::vector<double> near_t;
			for (size_t j = 0; j < band.size(); j++)
				if (std::abs((band[j] - f.circle.centre).norm() -
				             f.circle.radius_m) <= gate)
					near.push_back(band[j]), near_dir.push_back(band_dir[j]),
					    near_t.push_back(band_t[j]);
			Circle c = f.circle;
			if (near.size() >= size_t(o.min_dbh_points) &&
			    refineCircleGeometric(near, c) &&
			    c.radius_m >= fo.min_radius_m && c.radius_m <= fo.max_radius_m)
				f = evaluateCircle(near, c, fo);
			// Range noise is along the rays: where the viewing directions
			// are known, refine with along-ray residuals (unbiased on one-
			// sided arcs, where orthogonal ones shrink the circle; on small
			// stems seen from 10-15 m by a quarter of the radius). Where the
			// points carry times, the stem's centre may drift linearly in
			// time: a map whose poses drift while the stem is passed by
			// squashes the stem along the drift (doc/trees.md). A result
			// more than 60 % of the radius from the orthogonal one is not
			// trusted (a short, noisy arc the ray model cannot pin down).
			Points2D ray_p, ray_d;
			std::vector<double> ray_t;
			for (size_t j = 0; j < near.size(); j++)
				if (near_dir[j].squaredNorm() > 0)
					ray_p.push_back(near[j]), ray_d.push_back(near_dir[j]),
					    ray_t.push_back(near_t[j]);
			Circle cr = f.circle;
			RayFitOptions ro;
			if (point_times && o.dbh_drift_sigma_m_per_s > 0)
				ro.times = &ray_t,
				ro.drift_sigma_m_per_s = o.dbh_drift_sigma_m_per_s;
			if (o.dbh_along_rays &&
			    ray_p.size() >=
			        std::max<size_t>(o.min_dbh_points, near.size() / 2) &&
			    refineCircleAlongRays(ray_p, ray_d, cr, ro) &&
			    std::abs(cr.radius_m - f.circle.radius_m) <=
			        0.6 * f.circle.radius_m &&
			    (cr.centre - f.circle.centre).norm() <= f.circle.radius_m &&
			    cr.radius_m >= fo.min_radius_m &&
			    cr.radius_m <= fo.max_radius_m)
				f = evaluateCircle(near, cr, fo);
		}
		// Foliage at breast height around a stem seen from most sides (a
		// shrub at its foot) makes the robust circle too large, with a high
		// RMSE: the stem is solid, so a ring with the foliage outside and
		// nothing inside is the stem (fitSolidRing). Only for such stems:
		// on clean, noisy or one-sided rings it picks an inner ring of the
		// noise and shrinks the DBH (applied above an RMSE of 2 cm, the
		// handheld bias went from 0 to -0.8 cm). Tried before the multi-view
		// fit, whose gate follows the spread of the points it keeps: it
		// drops most of the foliage and leaves a ring too large with an RMSE
		// that passes for a clean one (handheld seed 3: five stems in shrubs
		// read 4-6 cm too large). A solid ring found is not refitted there
		// (its scale over the whole band would let the foliage back in).
		bool solid = false;
		auto trySolidRing = [&]
		{
			if (!f.ok || f.rmse_m <= kSolidMinRmseM ||
			    f.arc_coverage_deg < kSolidMinArcDeg)
				return;
			const Circle c = fitSolidRing(band, f.circle, 2 * o.ransac_inlier_m,
			                              kSolidRingIterations, o.seed);
			if (c.radius_m < f.circle.radius_m - kSolidMinShrinkM &&
			    c.radius_m >= fo.min_radius_m)
			{
				f = evaluateCircle(band, c, fo);
				st.solid_rings++;
				solid = true;
			}
		};
		trySolidRing();
		// Multi-view: the breast-height points of every time segment, one
		// shift per segment (pose errors between segments would blur the
		// ring; a blurred or doubled ring fits one circle too large). Only
		// a blurred circle (fit RMSE above good_rmse_m) can take its result
		// (see below), so a sharp one skips it: it was 5 % of a ground-truth-
		// pose run's CPU, spent on stems that kept their single circle.
		bool multi_view = false;
		if (!solid && f.ok && !s_grid.empty() && f.rmse_m > o.good_rmse_m)
		{
			Points2D sp, sd;
			std::vector<uint32_t> ss;
			std::vector<uint8_t> sc;
			const double reach_s = 1.6 * r_est + 0.1;
			for (int iy =
			         std::max(0, int((xy0.y() - reach_s - s_lo.y()) / cell));
			     iy <=
			     std::min(sgy - 1, int((xy0.y() + reach_s - s_lo.y()) / cell));
			     iy++)
				for (int ix = std::max(
				         0, int((xy0.x() - reach_s - s_lo.x()) / cell));
				     ix <= std::min(sgx - 1,
				                    int((xy0.x() + reach_s - s_lo.x()) / cell));
				     ix++)
					for (const uint32_t i : s_grid[ix + sgx * iy])
					{
						if (std::abs(s_hag[i] - o.dbh_height_m) >
						    o.dbh_segment_band_half_m)
							continue;
						const Eigen::Vector3d d = segments->pts[i] - p0;
						const Eigen::Vector2d q(d.dot(e1), d.dot(e2));
						if (std::abs((q - f.circle.centre).norm() -
						             f.circle.radius_m) >
						    0.5 * f.circle.radius_m)
							continue;
						Eigen::Vector2d v = Eigen::Vector2d::Zero();
						if (o.dbh_along_rays)
						{
							const Eigen::Vector3d w =
							    segments->dirs[i].cast<double>();
							v = Eigen::Vector2d(w.dot(e1), w.dot(e2));
							v = v.norm() > 0.5 ? Eigen::Vector2d(v.normalized())
							                   : Eigen::Vector2d::Zero();
						}
						sp.push_back(q), sd.push_back(v);
						ss.push_back(segments->segment[i]);
						sc.push_back(segments->range_class.empty()
						                 ? 0
						                 : segments->range_class[i]);
					}
			const double gate = std::max(4 * f.scale_m, 2 * o.ransac_inlier_m);
			// The nearest range classes that see enough of the stem: pose
			// errors (rotations) move far points most.
			uint8_t max_class = 0;
			for (const uint8_t c : sc) max_class = std::max(max_class, c);
			for (uint8_t k = 0; k < max_class; k++)
			{
				Points2D near_k;
				for (size_t j = 0; j < sp.size(); j++)
					if (sc[j] <= k) near_k.push_back(sp[j]);
				if (near_k.size() >= 2 * size_t(o.min_dbh_points) &&
				    arcCoverageDeg(near_k, f.circle, gate, o.arc_bin_deg) >=
				        o.good_arc_deg)
				{
					max_class = k;
					break;
				}
			}
			size_t w = 0;
			for (size_t j = 0; j < sp.size(); j++)
				if (sc[j] <= max_class)
					sp[w] = sp[j], sd[w] = sd[j], ss[w] = ss[j], w++;
			sp.resize(w), sd.resize(w), ss.resize(w);
			const auto g = fitDbhSegments(sp, sd, ss, f.circle, gate, o,
			                              fo.min_radius_m, fo.max_radius_m);
			// Where each segment sees one side of the stem, its shift towards
			// its sensor and a larger radius fit alike (only the shift prior
			// holds them): the multi-view circle is taken only for a stem
			// whose single circle is blurred (fit RMSE above good_rmse_m),
			// and not if it sees less of the stem than the single circle.
			if (g.ok && g.arc_coverage_deg >= 0.8 * f.arc_coverage_deg)
				f = g, multi_view = true;
		}
		// A multi-view circle still blurred by foliage.
		if (multi_view) trySolidRing();
		// A circle seeing far less of the stem than its slices, with another
		// radius, is a small circle through part of the ring (a local
		// optimum; the robot run's GT 1465: 50 deg and r 10.3 cm where six
		// slices saw 180-215 deg at 18.4-19.8 cm, GT 19.7 cm).
		f = checkAgainstReference(
		    band, f,
		    Circle{Eigen::Vector2d::Zero(), c.radiusAt(o.dbh_height_m)},
		    c.medianArcDeg(), fo, size_t(o.min_dbh_points));
		// A small stem's radius from the lateral spread of its rays too
		// (silhouetteRadius; TreeOptions::dbh_silhouette_max_m): the mean of
		// both, fading out towards the larger stems, where a voxel merges
		// many rays at the stem's front and the spread reads low.
		if (f.ok && o.dbh_silhouette_max_m > 0 &&
		    2 * f.circle.radius_m < o.dbh_silhouette_max_m)
		{
			const double full = 0.75 * o.dbh_silhouette_max_m;
			const double w =
			    0.5 *
			    std::clamp((o.dbh_silhouette_max_m - 2 * f.circle.radius_m) /
			                   (o.dbh_silhouette_max_m - full),
			               0.0, 1.0);
			const double rs =
			    silhouetteRadius(band, band_dir, f.circle, kSilhouetteReachM,
			                     size_t(o.min_dbh_points));
			if (std::isfinite(rs))
				f.circle.radius_m = w * rs + (1 - w) * f.circle.radius_m;
		}
		if (f.ok)
		{
			const Eigen::Vector3d centre =
			    p0 + f.circle.centre.x() * e1 + f.circle.centre.y() * e2;
			rec.x = centre.x();
			rec.y = centre.y();
			rec.dbh_m = 2 * f.circle.radius_m;
			rec.fit_rmse_m = f.rmse_m;
			rec.arc_coverage_deg = f.arc_coverage_deg;
			if (f.arc_coverage_deg < o.good_arc_deg) rec.quality |= kPartialArc;
			if (f.rmse_m > o.good_rmse_m) rec.quality |= kHighRmse;
		}
		else
		{
			rec.x = xy0.x();
			rec.y = xy0.y();
			rec.dbh_m = 2 * c.radiusAt(o.dbh_height_m);
			rec.quality |= kDbhFromSlices;
			double rm = 0, am = 0;
			for (const auto& q : c.s)
				rm = std::max(rm, q.rmse_m), am = std::max(am, q.arc_deg);
			rec.fit_rmse_m = rm;
			rec.arc_coverage_deg = am;
		}
		rec.z_ground = terrain.heightAt(rec.x, rec.y);
		// Top: walk up the column above the slices until a vertical gap.
		std::sort(column_h.begin(), column_h.end());
		double top = hi_h;
		for (double h : column_h)
		{
			if (h - top > o.top_max_gap_m) break;
			top = h;
		}
		if (top - hi_h < 1.0)
			rec.quality |= kTopNotSeen;
		else
			rec.height_m = top;
		trees.push_back(std::move(t));
	}
	std::sort(trees.begin(), trees.end(),
	          [](const DetectedTree& a, const DetectedTree& b)
	          {
		          return a.record.x != b.record.x ? a.record.x < b.record.x
		                                          : a.record.y < b.record.y;
	          });
	for (size_t i = 0; i < trees.size(); i++)
		trees[i].record.id = uint32_t(i + 1);
	if (stats) *stats = st;
	return trees;
}

std::vector<map::TreeRecord> toRecords(const std::vector<DetectedTree>& trees)
{
	std::vector<map::TreeRecord> r;
	for (const auto& t : trees) r.push_back(t.record);
	return r;
}

}  // namespace forest_slam::trees
