#include <forest_slam/eval/hungarian.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

namespace forest_slam::eval
{
std::vector<int> hungarian(const Eigen::MatrixXd& cost)
{
	const int rows = static_cast<int>(cost.rows());
	const int cols = static_cast<int>(cost.cols());
	std::vector<int> result(rows, -1);
	if (rows == 0 || cols == 0) return result;
	if (!cost.allFinite())
		throw std::invalid_argument(
		    "hungarian: cost matrix has non-finite entries");
	// The potentials formulation needs n <= m; solve the transpose otherwise.
	const bool transposed = rows > cols;
	const Eigen::MatrixXd a =
	    transposed ? Eigen::MatrixXd(cost.transpose()) : cost;
	const int n = static_cast<int>(a.rows()), m = static_cast<int>(a.cols());
	const double inf = std::numeric_limits<double>::infinity();
	// 1-based arrays; column 0 is a virtual column holding the row being added.
	std::vector<double> u(n + 1, 0), v(m + 1, 0);
	std::vector<int> p(m + 1, 0), way(m + 1, 0);
	for (int i = 1; i <= n; i++)
	{
		p[0] = i;
		int j0 = 0;
		std::vector<double> minv(m + 1, inf);
		std::vector<char> used(m + 1, 0);
		do
		{
			used[j0] = 1;
			const int i0 = p[j0];
			double delta = inf;
			int j1 = 0;
			for (int j = 1; j <= m; j++)
			{
				if (used[j]) continue;
				const double cur = a(i0 - 1, j - 1) - u[i0] - v[j];
				if (cur < minv[j])
				{
					minv[j] = cur;
					way[j] = j0;
				}
				if (minv[j] < delta)
				{
					delta = minv[j];
					j1 = j;
				}
			}
			for (int j = 0; j <= m; j++)
			{
				if (used[j])
				{
					u[p[j]] += delta;
					v[j] -= delta;
				}
				else
					minv[j] -= delta;
			}
			j0 = j1;
		} while (p[j0] != 0);
		do
		{
			const int j1 = way[j0];
			p[j0] = p[j1];
			j0 = j1;
		} while (j0 != 0);
	}
	for (int j = 1; j <= m; j++)
	{
		if (p[j] == 0) continue;
		if (transposed)
			result[j - 1] = p[j] - 1;
		else
			result[p[j] - 1] = j - 1;
	}
	return result;
}

namespace
{
struct UnionFind
{
	std::vector<size_t> parent;
	explicit UnionFind(size_t n) : parent(n)
	{
		std::iota(parent.begin(), parent.end(), 0);
	}
	size_t find(size_t x)
	{
		while (parent[x] != x) x = parent[x] = parent[parent[x]];
		return x;
	}
	void unite(size_t x, size_t y) { parent[find(x)] = find(y); }
};

struct CellHash
{
	size_t operator()(const std::pair<int64_t, int64_t>& c) const
	{
		return std::hash<int64_t>()(c.first * 73856093LL) ^
		       std::hash<int64_t>()(c.second * 19349663LL);
	}
};
}  // namespace

std::vector<GatedMatch> matchGated(const std::vector<Eigen::Vector2d>& a,
                                   const std::vector<Eigen::Vector2d>& b,
                                   double gate_m)
{
	if (!(gate_m > 0) || !std::isfinite(gate_m))
		throw std::invalid_argument("matchGated: gate must be positive");
	// Candidate pairs through a grid of gate-sized cells: a partner within the
	// gate lies in the same or an adjacent cell.
	auto cellOf = [&](const Eigen::Vector2d& p)
	{
		return std::make_pair(static_cast<int64_t>(std::floor(p.x() / gate_m)),
		                      static_cast<int64_t>(std::floor(p.y() / gate_m)));
	};
	std::unordered_map<std::pair<int64_t, int64_t>, std::vector<size_t>,
	                   CellHash>
	    grid;
	for (size_t j = 0; j < b.size(); j++) grid[cellOf(b[j])].push_back(j);

	struct Edge
	{
		size_t i, j;
		double d;
	};
	std::vector<Edge> edges;
	UnionFind uf(a.size() + b.size());
	for (size_t i = 0; i < a.size(); i++)
	{
		const auto c = cellOf(a[i]);
		for (int64_t dx = -1; dx <= 1; dx++)
			for (int64_t dy = -1; dy <= 1; dy++)
			{
				const auto it = grid.find({c.first + dx, c.second + dy});
				if (it == grid.end()) continue;
				for (size_t j : it->second)
				{
					const double d = (a[i] - b[j]).norm();
					if (d > gate_m) continue;
					edges.push_back({i, j, d});
					uf.unite(i, a.size() + j);
				}
			}
	}

	// Group edges by component; each component is an independent assignment.
	std::map<size_t, std::vector<size_t>> comp_edges;
	for (size_t e = 0; e < edges.size(); e++)
		comp_edges[uf.find(edges[e].i)].push_back(e);

	std::vector<GatedMatch> out;
	for (const auto& [root, eids] : comp_edges)
	{
		std::vector<size_t> ai, bj;
		for (size_t e : eids)
		{
			ai.push_back(edges[e].i);
			bj.push_back(edges[e].j);
		}
		std::sort(ai.begin(), ai.end());
		ai.erase(std::unique(ai.begin(), ai.end()), ai.end());
		std::sort(bj.begin(), bj.end());
		bj.erase(std::unique(bj.begin(), bj.end()), bj.end());
		auto idx = [](const std::vector<size_t>& v, size_t x)
		{
			return static_cast<size_t>(std::lower_bound(v.begin(), v.end(), x) -
			                           v.begin());
		};
		// A forbidden pair costs more than any set of allowed pairs can save,
		// so the optimum first maximises the number of allowed pairs.
		const size_t q = std::min(ai.size(), bj.size());
		const double forbidden = gate_m * static_cast<double>(q + 1) + 1.0;
		Eigen::MatrixXd cost = Eigen::MatrixXd::Constant(
		    static_cast<Eigen::Index>(ai.size()),
		    static_cast<Eigen::Index>(bj.size()), forbidden);
		for (size_t e : eids)
			cost(static_cast<Eigen::Index>(idx(ai, edges[e].i)),
			     static_cast<Eigen::Index>(idx(bj, edges[e].j))) = edges[e].d;
		const auto assign = hungarian(cost);
		for (size_t r = 0; r < assign.size(); r++)
		{
			if (assign[r] < 0) continue;
			const double d = cost(static_cast<Eigen::Index>(r), assign[r]);
			if (d >= forbidden) continue;
			out.push_back({ai[r], bj[static_cast<size_t>(assign[r])], d});
		}
	}
	std::sort(out.begin(), out.end(),
	          [](const GatedMatch& x, const GatedMatch& y)
	          { return x.a < y.a; });
	return out;
}

}  // namespace forest_slam::eval
