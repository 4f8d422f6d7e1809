// forest-eval: the paper's evaluation figures for a trajectory (`traj`) or a
// tree map (`trees`). Argument parsing only; metrics live in libs/eval.
#include <forest_slam/core/atomic_file.h>
#include <forest_slam/eval/csv_table.h>
#include <forest_slam/eval/traj_report.h>
#include <forest_slam/eval/tree_report.h>
#include <forest_slam/io/tum.h>

#include <exception>
#include <functional>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
using namespace forest_slam;

const char* kMainUsage =
    R"(Usage: forest-eval <command> [options]

Commands:
  traj    trajectory metrics: ATE, RPE, vertical drift, return-to-start error
          (paper Table 5), drift against GNSS every 10 s (paper Table 6)
  trees   tree-map metrics: matching, recall/precision/F1, position and DBH
          errors (paper Tables 3-4)

Run 'forest-eval <command> --help' for the options of a command.
Exit codes: 0 success, 1 runtime error (unreadable/malformed input, no time
overlap, cannot write output), 2 usage error. Definitions: doc/evaluation.md.
)";

const char* kTrajUsage =
    R"(Usage: forest-eval traj --est EST.tum [--gt GT.tum] [--gnss GNSS_FILE]
                        [--json FILE] [--svg FILE] [options]

Inputs (TUM: "t x y z qx qy qz qw" per line, '#' comments):
  --est FILE               estimated trajectory (required)
  --gt FILE                ground truth; needed for ATE, RPE, vertical drift
  --gnss FILE              GNSS track in the map frame: TUM, or CSV with a
                           header naming columns t,x,y,z (others ignored)
Outputs (written atomically):
  --json FILE              all figures as JSON
  --svg FILE               top view (GT, estimate, aligned estimate, GNSS) and
                           height profile
Options:
  --max-gap-s S            do not interpolate the GT across gaps longer than
                           S seconds (default 1.0)
  --rpe-lengths-m LIST     comma-separated RPE segment lengths in metres
                           (default 10,20,30,40,50,60,70,80,90,100)
  --gnss-interval-s S      GNSS drift sample interval (default 10)
  --gnss-max-offset-s S    use the GNSS fix nearest to each sample time if
                           within S seconds, else skip it (default 0.5)
  -h, --help               this help
)";

const char* kTreesUsage =
    R"(Usage: forest-eval trees --gt GT.csv --est EST.csv [--max-match-m 0.5]
                         [--min-dbh-m 0.10] [--max-range-m R --traj EST.tum]
                         [--regions FILE] [--json FILE] [--svg FILE]

Inputs (CSV with a header; columns found by name, extra columns ignored):
  --gt FILE                reference trees: id,x,y,dbh_m [,sapling]
  --est FILE               estimated trees: id,x,y,dbh_m
  --traj FILE              trajectory (TUM) defining the evaluated area
  --regions FILE           CSV name,xmin,ymin,xmax,ymax: per-region table
                           (default: one region "all")
Outputs (written atomically):
  --json FILE              all figures as JSON (with per-tree matches)
  --svg FILE               tree map and DBH estimated vs reference
Options:
  --max-match-m M          matching gate on horizontal distance (default 0.5)
  --min-dbh-m D            evaluate GT trees with DBH >= D metres (default
                           0.10); saplings are never evaluated
  --max-range-m R          evaluate only trees within R metres (horizontal)
                           of the --traj trajectory; needs --traj
  -h, --help               this help
)";

struct UsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

struct ParsedArgs
{
	std::map<std::string, std::string> values;
	bool help = false;
	bool has(const std::string& k) const { return values.count(k) > 0; }
	std::string get(const std::string& k, const std::string& def = "") const
	{
		const auto it = values.find(k);
		return it == values.end() ? def : it->second;
	}
};

/** Every option takes one value ("--opt V" or "--opt=V"), except --help. */
ParsedArgs parseArgs(int argc, char** argv, int first,
                     const std::set<std::string>& known)
{
	ParsedArgs a;
	for (int i = first; i < argc; i++)
	{
		std::string arg = argv[i];
		if (arg == "-h" || arg == "--help")
		{
			a.help = true;
			continue;
		}
		if (arg.rfind("--", 0) != 0)
			throw UsageError("unexpected argument '" + arg + "'");
		std::string value;
		bool has_value = false;
		const auto eq = arg.find('=');
		if (eq != std::string::npos)
		{
			value = arg.substr(eq + 1);
			arg = arg.substr(0, eq);
			has_value = true;
		}
		if (!known.count(arg)) throw UsageError("unknown option '" + arg + "'");
		if (!has_value)
		{
			if (i + 1 >= argc)
				throw UsageError("option " + arg + " needs a value");
			value = argv[++i];
		}
		if (value.empty())
			throw UsageError("option " + arg + " has an empty value");
		if (!a.values.emplace(arg, value).second)
			throw UsageError("option " + arg + " given twice");
	}
	return a;
}

double numberArg(const ParsedArgs& a, const std::string& k, double def,
                 bool strictly_positive)
{
	if (!a.has(k)) return def;
	const auto v = eval::parseFiniteNumber(a.get(k));
	if (!v) throw UsageError(k + ": expected a number, got '" + a.get(k) + "'");
	if (strictly_positive ? !(*v > 0) : !(*v >= 0))
		throw UsageError(k + ": expected a value " +
		                 (strictly_positive ? "> 0" : ">= 0") + ", got '" +
		                 a.get(k) + "'");
	return *v;
}

std::vector<double> listArg(const ParsedArgs& a, const std::string& k,
                            const std::vector<double>& def)
{
	if (!a.has(k)) return def;
	std::vector<double> out;
	const std::string s = a.get(k);
	size_t start = 0;
	while (true)
	{
		const auto comma = s.find(',', start);
		const std::string item =
		    s.substr(start, comma == std::string::npos ? std::string::npos
		                                               : comma - start);
		const auto v = eval::parseFiniteNumber(item);
		if (!v || !(*v > 0))
			throw UsageError(k +
			                 ": expected comma-separated numbers > 0, got '" +
			                 item + "' in '" + s + "'");
		out.push_back(*v);
		if (comma == std::string::npos) break;
		start = comma + 1;
	}
	return out;
}

void writeOutputs(const ParsedArgs& a,
                  const std::function<void(std::ostream&)>& json,
                  const std::function<void(std::ostream&)>& svg)
{
	if (a.has("--json")) core::writeFileAtomically(a.get("--json"), json);
	if (a.has("--svg")) core::writeFileAtomically(a.get("--svg"), svg);
}

int runTraj(int argc, char** argv)
{
	const auto a = parseArgs(
	    argc, argv, 2,
	    {"--gt", "--est", "--gnss", "--json", "--svg", "--max-gap-s",
	     "--rpe-lengths-m", "--gnss-interval-s", "--gnss-max-offset-s"});
	if (a.help)
	{
		std::cout << kTrajUsage;
		return 0;
	}
	if (!a.has("--est")) throw UsageError("--est is required");
	eval::TrajEvalOptions opts;
	opts.association.max_gt_gap_s =
	    numberArg(a, "--max-gap-s", opts.association.max_gt_gap_s, true);
	opts.rpe.lengths_m = listArg(a, "--rpe-lengths-m", opts.rpe.lengths_m);
	opts.gnss.interval_s =
	    numberArg(a, "--gnss-interval-s", opts.gnss.interval_s, true);
	opts.gnss.max_fix_offset_s =
	    numberArg(a, "--gnss-max-offset-s", opts.gnss.max_fix_offset_s, false);

	eval::TrajEvalInputs in;
	in.est_path = a.get("--est");
	in.est = io::readTum(in.est_path);
	if (a.has("--gt"))
	{
		in.gt_path = a.get("--gt");
		in.gt = io::readTum(in.gt_path);
	}
	if (a.has("--gnss"))
	{
		in.gnss_path = a.get("--gnss");
		in.gnss = eval::readPositionTrack(in.gnss_path);
	}
	const auto report = eval::evaluateTrajectory(in, opts);
	eval::printTrajReport(std::cout, in, report);
	writeOutputs(
	    a, [&](std::ostream& os) { eval::writeTrajJson(os, in, report); },
	    [&](std::ostream& os) { eval::writeTrajSvg(os, in, report); });
	return 0;
}

int runTrees(int argc, char** argv)
{
	const auto a =
	    parseArgs(argc, argv, 2,
	              {"--gt", "--est", "--max-match-m", "--min-dbh-m",
	               "--max-range-m", "--traj", "--regions", "--json", "--svg"});
	if (a.help)
	{
		std::cout << kTreesUsage;
		return 0;
	}
	if (!a.has("--gt")) throw UsageError("--gt is required");
	if (!a.has("--est")) throw UsageError("--est is required");
	if (a.has("--max-range-m") != a.has("--traj"))
		throw UsageError("--max-range-m and --traj go together");
	eval::TreeEvalOptions opts;
	opts.max_match_m = numberArg(a, "--max-match-m", opts.max_match_m, true);
	opts.min_dbh_m = numberArg(a, "--min-dbh-m", opts.min_dbh_m, false);
	opts.max_range_m = numberArg(a, "--max-range-m", 0.0, true);

	eval::TreeEvalInputs in;
	in.gt_path = a.get("--gt");
	in.est_path = a.get("--est");
	in.gt = eval::readTreesCsv(in.gt_path);
	in.est = eval::readTreesCsv(in.est_path);
	if (a.has("--traj"))
	{
		in.traj_path = a.get("--traj");
		in.traj = io::readTum(in.traj_path);
		if (in.traj.empty())
			throw std::runtime_error(
			    "trajectory '" + in.traj_path +
			    "' has no poses, cannot apply --max-range-m");
	}
	if (a.has("--regions"))
	{
		in.regions_path = a.get("--regions");
		in.regions = eval::readRegionsCsv(in.regions_path);
	}
	const auto ev = eval::evaluateTrees(
	    in.gt, in.est, opts, in.traj,
	    in.regions.empty() ? std::vector<eval::Region>{eval::allRegion()}
	                       : in.regions);
	eval::printTreeReport(std::cout, in, opts, ev);
	writeOutputs(
	    a, [&](std::ostream& os) { eval::writeTreeJson(os, in, opts, ev); },
	    [&](std::ostream& os) { eval::writeTreeSvg(os, in, opts, ev); });
	return 0;
}
}  // namespace

int main(int argc, char** argv)
{
	const std::string cmd = argc > 1 ? argv[1] : "";
	try
	{
		if (cmd == "-h" || cmd == "--help")
		{
			std::cout << kMainUsage;
			return 0;
		}
		if (cmd == "traj") return runTraj(argc, argv);
		if (cmd == "trees") return runTrees(argc, argv);
		throw UsageError(cmd.empty() ? "missing command (traj or trees)"
		                             : "unknown command '" + cmd + "'");
	}
	catch (const UsageError& e)
	{
		std::cerr << "forest-eval"
		          << (cmd == "traj" || cmd == "trees" ? " " + cmd : "")
		          << ": usage error: " << e.what() << "\n"
		          << "Run 'forest-eval"
		          << (cmd == "traj" || cmd == "trees" ? " " + cmd : "")
		          << " --help' for usage.\n";
		return 2;
	}
	catch (const std::exception& e)
	{
		std::cerr << "forest-eval " << cmd << ": error: " << e.what() << "\n";
		return 1;
	}
}
