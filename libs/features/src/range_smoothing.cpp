#include <forest_slam/features/range_smoothing.h>

#include <cmath>

namespace forest_slam::features
{
namespace
{
/** Weights of the centre of a quadratic least-squares fit over 2h+1 equally
 * spaced samples (Savitzky-Golay): w_j for offsets 0..h. */
std::vector<float> savitzkyGolayQuadratic(int h)
{
	std::vector<float> w(h + 1);
	const double den = (2.0 * h - 1) * (2.0 * h + 1) * (2.0 * h + 3);
	for (int j = 0; j <= h; j++)
		w[j] = static_cast<float>(
		    (3.0 * (3.0 * h * h + 3.0 * h - 1) - 15.0 * j * j) / den);
	return w;
}

/** Whether b, fired right after a on the same ring, hit the same object. */
bool sameRun(const FeatureInputPoint& a, const FeatureInputPoint& b, float ra,
             float rb, float max_step)
{
	if (b.column != a.column + 1 || a.ground != b.ground) return false;
	if (!a.ground && (a.cluster < 0 || a.cluster != b.cluster)) return false;
	return std::abs(ra - rb) < max_step;
}
}  // namespace

std::vector<Eigen::Vector3f> smoothRanges(
    const std::vector<FeatureInputPoint>& pts, const RangeSmoothingOptions& o)
{
	std::vector<Eigen::Vector3f> out(pts.size());
	for (size_t i = 0; i < pts.size(); i++) out[i] = pts[i].xyz;
	const int h = o.half_window;
	if (h <= 0 || pts.empty()) return out;
	const std::vector<float> w = savitzkyGolayQuadratic(h);
	const float max_step = static_cast<float>(o.max_step_m);
	const RingLines lines = ringLines(pts);
	std::vector<float> range;
	for (int ring = 0; ring < lines.rings(); ring++)
	{
		const uint32_t* line = lines.index.data() + lines.start[ring];
		const int n =
		    static_cast<int>(lines.start[ring + 1] - lines.start[ring]);
		range.resize(n);
		for (int k = 0; k < n; k++) range[k] = pts[line[k]].xyz.norm();
		// Runs of the same object; the points at least h from both ends.
		int run_start = 0;
		for (int k = 1; k <= n; k++)
		{
			if (k < n && sameRun(pts[line[k - 1]], pts[line[k]], range[k - 1],
			                     range[k], max_step))
				continue;
			for (int m = run_start + h; m + h < k; m++)
			{
				float r = w[0] * range[m];
				for (int j = 1; j <= h; j++)
					r += w[j] * (range[m - j] + range[m + j]);
				if (range[m] > 0 && r > 0)
					out[line[m]] = pts[line[m]].xyz * (r / range[m]);
			}
			run_start = k;
		}
	}
	return out;
}

}  // namespace forest_slam::features
