#include <forest_slam/trees/outlier_filter.h>

#include <nanoflann.hpp>

#include <cmath>

namespace forest_slam::trees
{
namespace
{
struct Adaptor
{
	const Points2D& p;
	size_t kdtree_get_point_count() const { return p.size(); }
	double kdtree_get_pt(size_t i, size_t d) const { return p[i][int(d)]; }
	template <class B>
	bool kdtree_get_bbox(B&) const
	{
		return false;
	}
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<double, Adaptor>, Adaptor, 2, size_t>;
}  // namespace

std::vector<size_t> statisticalOutlierFilter(const Points2D& p, int k,
                                             double omega)
{
	std::vector<size_t> keep;
	if (k < 1 || p.size() < size_t(k) + 1)
	{
		for (size_t i = 0; i < p.size(); i++) keep.push_back(i);
		return keep;
	}
	Adaptor ad{p};
	Tree tree(2, ad, nanoflann::KDTreeSingleIndexAdaptorParams(10));
	tree.buildIndex();
	std::vector<double> mean_d(p.size());
	std::vector<size_t> idx(k + 1);
	std::vector<double> d2(k + 1);
	for (size_t i = 0; i < p.size(); i++)
	{
		const double q[2] = {p[i].x(), p[i].y()};
		const size_t n = tree.knnSearch(q, k + 1, idx.data(), d2.data());
		double s = 0;
		int m = 0;
		for (size_t j = 0; j < n; j++)
			if (idx[j] != i)
				s += std::sqrt(d2[j]), m++;  // skip the point itself
		mean_d[i] = m ? s / m : 0;
	}
	double mu = 0, var = 0;
	for (double v : mean_d) mu += v;
	mu /= double(p.size());
	for (double v : mean_d) var += (v - mu) * (v - mu);
	const double sigma = std::sqrt(var / double(p.size()));
	for (size_t i = 0; i < p.size(); i++)
		if (mean_d[i] <= mu + omega * sigma) keep.push_back(i);
	return keep;
}

}  // namespace forest_slam::trees
