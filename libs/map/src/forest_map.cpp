#include <forest_slam/core/atomic_file.h>
#include <forest_slam/core/config.h>
#include <forest_slam/core/memory.h>
#include <forest_slam/core/scan_points.h>
#include <forest_slam/map/forest_map.h>

#include <mrpt/maps/CPointsMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/opengl/CPointCloud.h>
#include <mrpt/opengl/CSetOfObjects.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/stl_serialization.h>

#include <cmath>
#include <cstdio>
#include <mutex>
#include <sstream>
#include <stdexcept>

using namespace forest_slam::map;

IMPLEMENTS_SERIALIZABLE(CForestMap, CMetricMap, forest_slam::map)

// Factory names: the fully qualified C++ name and the short INI prefix used
// in CMultiMetricMap sections ("forestMap_count=1").
MAP_DEFINITION_REGISTER("forest_slam::map::CForestMap,forestMap",
                        forest_slam::map::CForestMap)

namespace forest_slam::map
{
void registerForestMapClasses()
{
	static std::once_flag once;
	std::call_once(once,
	               []
	               {
		               mrpt::rtti::registerClass(CLASS_ID(CForestMap));
		               (void)CForestMap::m_private_map_register_id;
	               });
}

namespace
{
// Also register at load time for code that does not call the function.
const bool g_registered = (registerForestMapClasses(), true);

Eigen::Isometry3d toIsometry(const mrpt::poses::CPose3D& p)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.matrix() =
	    p.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
	return T;
}

/** Points of an observation we know how to read, in the sensor frame, split
 * by ring when the sensor has rings (for smoothness). */
bool observationPoints(const mrpt::obs::CObservation& obs,
                       std::vector<std::vector<Eigen::Vector3f>>& rings,
                       mrpt::poses::CPose3D& sensor_pose)
{
	using namespace mrpt::obs;
	rings.clear();
	// Raw CObservationVelodyneScan packets are not accepted here: MRPT
	// 2.5.8's fromVelodyne() drops half of the returns; convert them with
	// ingest::velodyneToRotatingScan() first (the pipeline does).
	const auto* rot = dynamic_cast<const CObservationRotatingScan*>(&obs);
	if (rot)
	{
		const auto* model = core::findLidarModel(rot->lidarModel);
		if (!model || model->rings() != rot->rowCount) return false;
		const auto sp = core::unpackRotatingScan(*rot, *model);
		rings.resize(rot->rowCount);
		for (const auto& p : sp.points)
			rings[p.ring].emplace_back(p.x, p.y, p.z);
		sensor_pose = rot->sensorPose;
		return true;
	}
	if (auto* pc = dynamic_cast<const CObservationPointCloud*>(&obs))
	{
		if (!pc->pointcloud) return false;
		rings.resize(1);
		const auto& xs = pc->pointcloud->getPointsBufferRef_x();
		const auto& ys = pc->pointcloud->getPointsBufferRef_y();
		const auto& zs = pc->pointcloud->getPointsBufferRef_z();
		for (size_t i = 0; i < xs.size(); i++)
			rings[0].emplace_back(xs[i], ys[i], zs[i]);
		sensor_pose = pc->sensorPose;
		return true;
	}
	return false;
}

size_t submapEdgeCount(const CForestMap::SubmapTable& t)
{
	size_t n = 0;
	for (const auto& kv : t) n += kv.second.edge.size();
	return n;
}
size_t submapPlanarCount(const CForestMap::SubmapTable& t)
{
	size_t n = 0;
	for (const auto& kv : t) n += kv.second.planar.size();
	return n;
}
}  // namespace

// ---------------------------------------------------------------- options
void ForestMapOptions::loadFromConfigFile(
    const mrpt::config::CConfigFileBase& c, const std::string& s)
{
	FS_LOAD(c, s, submap_size_m);
	FS_LOAD(c, s, edge_voxel_m);
	FS_LOAD(c, s, planar_voxel_m);
	FS_LOAD(c, s, edge_smoothness_threshold);
	FS_LOAD(c, s, smoothness_half_window);
	FS_LOAD(c, s, max_insert_range_m);
	FS_LOAD(c, s, likelihood_sigma_m);
	FS_LOAD(c, s, likelihood_decimation);
	try
	{
		validate();
	}
	catch (const std::invalid_argument& e)
	{
		throw core::ConfigError(core::configOrigin(c) + ": [" + s + "] " +
		                        e.what());
	}
}

void ForestMapOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                        const std::string& s) const
{
	c.write(s, "submap_size_m", submap_size_m);
	c.write(s, "edge_voxel_m", edge_voxel_m);
	c.write(s, "planar_voxel_m", planar_voxel_m);
	c.write(s, "edge_smoothness_threshold", edge_smoothness_threshold);
	c.write(s, "smoothness_half_window", smoothness_half_window);
	c.write(s, "max_insert_range_m", max_insert_range_m);
	c.write(s, "likelihood_sigma_m", likelihood_sigma_m);
	c.write(s, "likelihood_decimation", likelihood_decimation);
}

void ForestMapOptions::validate() const
{
	auto positive = [](double v, const char* name)
	{
		if (!(v > 0))
			throw std::invalid_argument(
			    std::string(name) + " must be > 0, got " + std::to_string(v));
	};
	positive(submap_size_m, "submap_size_m");
	positive(edge_voxel_m, "edge_voxel_m");
	positive(planar_voxel_m, "planar_voxel_m");
	positive(max_insert_range_m, "max_insert_range_m");
	positive(likelihood_sigma_m, "likelihood_sigma_m");
	if (edge_voxel_m > submap_size_m || planar_voxel_m > submap_size_m)
		throw std::invalid_argument(
		    "voxel sizes must not exceed submap_size_m");
	if (smoothness_half_window < 1 || smoothness_half_window > 50)
		throw std::invalid_argument(
		    "smoothness_half_window must be in [1,50], got " +
		    std::to_string(smoothness_half_window));
	if (likelihood_decimation < 1)
		throw std::invalid_argument("likelihood_decimation must be >= 1");
}

// ------------------------------------------------------------ map factory
CForestMap::TMapDefinition::TMapDefinition() = default;

void CForestMap::TMapDefinition::loadFromConfigFile_map_specific(
    const mrpt::config::CConfigFileBase& source,
    const std::string& sectionNamePrefix)
{
	forestOpts.loadFromConfigFile(source, sectionNamePrefix + "_creationOpts");
}

void CForestMap::TMapDefinition::dumpToTextStream_map_specific(
    std::ostream& out) const
{
	forestOpts.dumpToTextStream(out);
}

mrpt::maps::CMetricMap* CForestMap::internal_CreateFromMapDefinition(
    const mrpt::maps::TMetricMapInitializer& _def)
{
	const auto& def = dynamic_cast<const CForestMap::TMapDefinition&>(_def);
	return new CForestMap(def.forestOpts);
}

// ------------------------------------------------------------- the map
CForestMap::CForestMap(const TOptions& opts) : opts_(opts)
{
	opts_.validate();
}

void CForestMap::setOptions(const TOptions& opts)
{
	opts.validate();
	const bool geometry_changed = opts.submap_size_m != opts_.submap_size_m ||
	                              opts.edge_voxel_m != opts_.edge_voxel_m ||
	                              opts.planar_voxel_m != opts_.planar_voxel_m;
	opts_ = opts;
	if (geometry_changed) internal_clear();
}

SubmapKey CForestMap::submapKeyOf(const Eigen::Vector3f& p) const
{
	return voxelKeyOf(p, static_cast<float>(1.0 / opts_.submap_size_m));
}

Submap& CForestMap::submapIn(SubmapTable& table, const Eigen::Vector3f& p) const
{
	const auto key = submapKeyOf(p);
	auto it = table.find(key);
	if (it == table.end())
	{
		Submap s;
		s.edge.setVoxelSize(static_cast<float>(opts_.edge_voxel_m));
		s.planar.setVoxelSize(static_cast<float>(opts_.planar_voxel_m));
		it = table.emplace(key, std::move(s)).first;
	}
	return it->second;
}

void CForestMap::startSegment()
{
	if (submaps_.empty()) return;  // nothing to keep apart yet
	// The segment's voxels move into one array, submap by submap (each
	// table freed once copied), in the order transformSegments reads the
	// tables: the merged map is the same, bit for bit.
	FrozenSegment seg;
	seg.edge = submapEdgeCount(submaps_);
	seg.planar = submapPlanarCount(submaps_);
	seg.voxels.reserve(seg.edge + seg.planar);
	seg.counts.reserve(submaps_.size());
	const auto copy = [&](const VoxelKey&, const VoxelCloud::Accum& a)
	{ seg.voxels.push_back(a); };
	for (auto it = submaps_.begin(); it != submaps_.end();
	     it = submaps_.erase(it))
	{
		it->second.edge.forEachVoxel(copy);
		it->second.planar.forEachVoxel(copy);
		seg.counts.emplace_back(it->second.edge.size(),
		                        it->second.planar.size());
	}
	frozen_.push_back(std::move(seg));
	submaps_ = SubmapTable();
	markDirty();
}

void CForestMap::transformSegments(
    const std::function<Eigen::Isometry3f(size_t, const Eigen::Vector3f&)>& T)
{
	SubmapTable out;
	const auto move =
	    [&](const VoxelCloud::Accum& a, bool edges, size_t segment)
	{
		const Eigen::Vector3f q = T(segment, a.centroid()) * a.centroid();
		if (!q.allFinite()) return;
		VoxelCloud::Accum b;
		b.sum = q * static_cast<float>(a.count);
		b.count = a.count;
		Submap& sm = submapIn(out, q);
		VoxelCloud& c = edges ? sm.edge : sm.planar;
		c.add(c.keyOf(q), b);
	};
	for (size_t s = 0; s < frozen_.size(); s++)
	{
		// Each segment is released once moved.
		const FrozenSegment seg = std::move(frozen_[s]);
		const VoxelCloud::Accum* v = seg.voxels.data();
		for (const auto& [edges, planar] : seg.counts)
		{
			for (uint32_t i = 0; i < edges; i++) move(*v++, true, s);
			for (uint32_t i = 0; i < planar; i++) move(*v++, false, s);
		}
	}
	const size_t current = frozen_.size();
	for (auto it = submaps_.begin(); it != submaps_.end();
	     it = submaps_.erase(it))
	{
		it->second.edge.forEachVoxel([&](const VoxelKey&, const auto& a)
		                             { move(a, true, current); });
		it->second.planar.forEachVoxel([&](const VoxelKey&, const auto& a)
		                               { move(a, false, current); });
	}
	frozen_.clear();
	submaps_ = std::move(out);
	markDirty();
}

void CForestMap::insertPoints(const std::vector<Eigen::Vector3f>& pts,
                              bool edges, const Eigen::Isometry3f& T)
{
	// A scan's consecutive points almost always share a 20 m submap: look
	// it up again only when the key changes (unordered_map elements keep
	// their address while others are added).
	// The voxel tables outgrow the caches: the slot of the point kAhead
	// further on is prefetched (in the current submap, where it almost
	// always falls), so the keys are computed first.
	thread_local std::vector<Eigen::Vector3f> q;
	thread_local std::vector<uint64_t> key;
	q.clear();
	key.clear();
	// Keys as the submaps' clouds compute them (same voxel size).
	const VoxelCloud probe(
	    static_cast<float>(edges ? opts_.edge_voxel_m : opts_.planar_voxel_m));
	for (const auto& p : pts)
		if (p.allFinite())
		{
			q.push_back(T * p);
			key.push_back(probe.keyOf(q.back()));
		}
	constexpr size_t kAhead = 16;
	SubmapKey last{};
	Submap* sm = nullptr;
	for (size_t n = 0; n < q.size(); n++)
	{
		const SubmapKey k = submapKeyOf(q[n]);
		if (!sm || !(k == last)) sm = &submapFor(q[n]), last = k;
		VoxelCloud& cloud = edges ? sm->edge : sm->planar;
		if (n + kAhead < q.size()) cloud.prefetch(key[n + kAhead]);
		cloud.insert(key[n], q[n]);
	}
}

void CForestMap::insertFeatures(const std::vector<Eigen::Vector3f>& edge_map,
                                const std::vector<Eigen::Vector3f>& planar_map)
{
	insertFeatures(edge_map, planar_map, Eigen::Isometry3d::Identity());
}

void CForestMap::insertFeatures(
    const std::vector<Eigen::Vector3f>& edge_sensor,
    const std::vector<Eigen::Vector3f>& planar_sensor,
    const Eigen::Isometry3d& sensor_to_map)
{
	const Eigen::Isometry3f T = sensor_to_map.cast<float>();
	insertPoints(edge_sensor, true, T);
	insertPoints(planar_sensor, false, T);
	markDirty();
}

std::vector<SubmapKey> CForestMap::submapsNear(const Eigen::Vector3d& c,
                                               double r) const
{
	std::vector<SubmapKey> keys;
	const double s = opts_.submap_size_m;
	const auto lo = voxelKeyOf((c.array() - r).matrix().cast<float>(), 1.f / s);
	const auto hi = voxelKeyOf((c.array() + r).matrix().cast<float>(), 1.f / s);
	for (int x = lo.x; x <= hi.x; x++)
		for (int y = lo.y; y <= hi.y; y++)
			for (int z = lo.z; z <= hi.z; z++)
			{
				const SubmapKey k{x, y, z};
				if (!submaps_.count(k)) continue;
				// Distance from the sphere centre to the cube.
				double d2 = 0;
				const int idx[3] = {x, y, z};
				for (int a = 0; a < 3; a++)
				{
					const double lo_a = idx[a] * s, hi_a = lo_a + s;
					const double v = c[a];
					if (v < lo_a)
						d2 += (lo_a - v) * (lo_a - v);
					else if (v > hi_a)
						d2 += (v - hi_a) * (v - hi_a);
				}
				if (d2 <= r * r) keys.push_back(k);
			}
	return keys;
}

void CForestMap::collectNear(const Eigen::Vector3d& centre, double radius_m,
                             std::vector<Eigen::Vector3f>& edge,
                             std::vector<Eigen::Vector3f>& planar) const
{
	edge.clear();
	planar.clear();
	for (const auto& k : submapsNear(centre, radius_m))
	{
		const auto& sm = submaps_.at(k);
		sm.edge.appendCentroids(edge);
		sm.planar.appendCentroids(planar);
	}
}

size_t CForestMap::memoryBytes() const
{
	size_t n = core::vectorBytes(frozen_) + core::hashMapBytes(submaps_);
	for (const auto& seg : frozen_)
		n += core::vectorBytes(seg.voxels) + core::vectorBytes(seg.counts);
	for (const auto& kv : submaps_)
		n += kv.second.edge.memoryBytes() + kv.second.planar.memoryBytes();
	return n;
}

size_t CForestMap::edgePointCount() const
{
	size_t n = submapEdgeCount(submaps_);
	for (const auto& seg : frozen_) n += seg.edge;
	return n;
}
size_t CForestMap::planarPointCount() const
{
	size_t n = submapPlanarCount(submaps_);
	for (const auto& seg : frozen_) n += seg.planar;
	return n;
}

mrpt::math::TBoundingBoxf CForestMap::boundingBox() const
{
	const auto* pts = getAsSimplePointsMap();
	if (!pts || pts->empty())
		return mrpt::math::TBoundingBoxf({0, 0, 0}, {0, 0, 0});
	return pts->boundingBox();
}

bool CForestMap::isEmpty() const
{
	return submaps_.empty() && frozen_.empty() && trees_.empty();
}

void CForestMap::internal_clear()
{
	submaps_.clear();
	frozen_.clear();
	trees_.clear();
	markDirty();
}

std::vector<uint8_t> smoothnessEdgeFlags(
    const std::vector<Eigen::Vector3f>& pts, int w, double edge_threshold)
{
	const int n = static_cast<int>(pts.size());
	std::vector<uint8_t> flags(pts.size(), 0);
	for (int i = w; i + w < n; i++)
	{
		// LOAM curvature: |sum_j (X_j - X_i)| / (|S| * |X_i|).
		Eigen::Vector3f diff = Eigen::Vector3f::Zero();
		for (int j = i - w; j <= i + w; j++)
			if (j != i) diff += pts[j] - pts[i];
		const float c = diff.norm() / (2 * w * std::max(pts[i].norm(), 1e-3f));
		flags[i] = c > edge_threshold ? 1 : 0;
	}
	return flags;
}

bool CForestMap::internal_insertObservation(
    const mrpt::obs::CObservation& obs,
    const std::optional<const mrpt::poses::CPose3D>& robotPose)
{
	std::vector<std::vector<Eigen::Vector3f>> rings;
	mrpt::poses::CPose3D sensor_pose;
	if (!observationPoints(obs, rings, sensor_pose)) return false;
	const mrpt::poses::CPose3D robot =
	    robotPose ? *robotPose : mrpt::poses::CPose3D();
	const Eigen::Isometry3d T = toIsometry(robot + sensor_pose);
	const float max_r2 =
	    static_cast<float>(opts_.max_insert_range_m * opts_.max_insert_range_m);

	std::vector<Eigen::Vector3f> edges, planar;
	for (auto& ring : rings)
	{
		std::vector<Eigen::Vector3f> kept;
		kept.reserve(ring.size());
		for (const auto& p : ring)
			if (p.allFinite() && p.squaredNorm() <= max_r2) kept.push_back(p);
		if (rings.size() > 1)
		{
			const auto flags =
			    smoothnessEdgeFlags(kept, opts_.smoothness_half_window,
			                        opts_.edge_smoothness_threshold);
			for (size_t i = 0; i < kept.size(); i++)
				(flags[i] ? edges : planar).push_back(kept[i]);
		}
		else
			planar.insert(planar.end(), kept.begin(), kept.end());
	}
	insertFeatures(edges, planar, T);
	return !edges.empty() || !planar.empty();
}

bool CForestMap::internal_canComputeObservationLikelihood(
    const mrpt::obs::CObservation& obs) const
{
	using namespace mrpt::obs;
	return dynamic_cast<const CObservationRotatingScan*>(&obs) ||
	       dynamic_cast<const CObservationPointCloud*>(&obs);
}

double CForestMap::internal_computeObservationLikelihood(
    const mrpt::obs::CObservation& obs,
    const mrpt::poses::CPose3D& takenFrom) const
{
	std::vector<std::vector<Eigen::Vector3f>> rings;
	mrpt::poses::CPose3D sensor_pose;
	if (!observationPoints(obs, rings, sensor_pose)) return 0;
	const Eigen::Isometry3f T =
	    toIsometry(takenFrom + sensor_pose).cast<float>();
	const double inv_2s2 =
	    1.0 / (2 * opts_.likelihood_sigma_m * opts_.likelihood_sigma_m);
	// Far from any centroid, a point contributes this floor (robustness).
	const double floor_lik = std::exp(-9.0 / 2);
	double log_lik = 0;
	size_t k = 0;
	for (const auto& ring : rings)
		for (const auto& p : ring)
		{
			if (k++ % opts_.likelihood_decimation) continue;
			const Eigen::Vector3f q = T * p;
			const auto it = submaps_.find(submapKeyOf(q));
			double best = std::numeric_limits<double>::max();
			if (it != submaps_.end())
			{
				Eigen::Vector3f c;
				float d2;
				if (it->second.planar.nearestAround(q, c, d2))
					best = std::min<double>(best, d2);
				if (it->second.edge.nearestAround(q, c, d2))
					best = std::min<double>(best, d2);
			}
			const double lik = best < 1e30 ? std::exp(-best * inv_2s2) : 0.0;
			log_lik += std::log(std::max(lik, floor_lik));
		}
	return log_lik;
}

const mrpt::maps::CSimplePointsMap* CForestMap::getAsSimplePointsMap() const
{
	if (!cached_points_)
	{
		auto pts = std::make_shared<mrpt::maps::CSimplePointsMap>();
		std::vector<Eigen::Vector3f> e, p;
		for (const auto& kv : submaps_)
		{
			kv.second.edge.appendCentroids(e);
			kv.second.planar.appendCentroids(p);
		}
		pts->reserve(e.size() + p.size());
		for (const auto& v : e) pts->insertPointFast(v.x(), v.y(), v.z());
		for (const auto& v : p) pts->insertPointFast(v.x(), v.y(), v.z());
		pts->mark_as_modified();
		cached_points_ = pts;
	}
	return cached_points_.get();
}

void CForestMap::getVisualizationInto(mrpt::opengl::CSetOfObjects& o) const
{
	if (!genericMapParams.enableSaveAs3DObject) return;
	auto edge = mrpt::opengl::CPointCloud::Create();
	auto planar = mrpt::opengl::CPointCloud::Create();
	edge->setColor(0.9f, 0.2f, 0.2f);
	planar->setColor(0.3f, 0.7f, 0.3f);
	for (const auto& kv : submaps_)
	{
		kv.second.edge.forEachVoxel(
		    [&](const VoxelKey&, const VoxelCloud::Accum& a)
		    {
			    const auto c = a.centroid();
			    edge->insertPoint(c.x(), c.y(), c.z());
		    });
		kv.second.planar.forEachVoxel(
		    [&](const VoxelKey&, const VoxelCloud::Accum& a)
		    {
			    const auto c = a.centroid();
			    planar->insertPoint(c.x(), c.y(), c.z());
		    });
	}
	o.insert(planar);
	o.insert(edge);
}

std::string CForestMap::asString() const
{
	std::ostringstream os;
	os << "CForestMap: " << submaps_.size() << " submaps of "
	   << opts_.submap_size_m << " m, " << edgePointCount() << " edge voxels ("
	   << opts_.edge_voxel_m << " m), " << planarPointCount()
	   << " planar voxels (" << opts_.planar_voxel_m << " m), " << trees_.size()
	   << " trees";
	return os.str();
}

void CForestMap::saveMetricMapRepresentationToFile(
    const std::string& prefix) const
{
	auto write_cloud = [&](const std::string& path, bool edges)
	{
		core::writeFileAtomically(
		    path,
		    [&](std::ostream& os)
		    {
			    char buf[96];
			    for (const auto& kv : submaps_)
				    (edges ? kv.second.edge : kv.second.planar)
				        .forEachVoxel(
				            [&](const VoxelKey&, const VoxelCloud::Accum& a)
				            {
					            const auto c = a.centroid();
					            std::snprintf(buf, sizeof(buf),
					                          "%.4f %.4f %.4f\n", c.x(), c.y(),
					                          c.z());
					            os << buf;
				            });
		    });
	};
	write_cloud(prefix + "_edge.xyz", true);
	write_cloud(prefix + "_planar.xyz", false);
	core::writeFileAtomically(
	    prefix + "_trees.csv",
	    [&](std::ostream& os)
	    {
		    os << "id,x,y,z_ground,dbh_m,height_m,n_points,fit_rmse_m,arc_"
		          "coverage_deg,n_slices,quality\n";
		    char buf[256];
		    for (const auto& t : trees_)
		    {
			    std::snprintf(
			        buf, sizeof(buf),
			        "%u,%.3f,%.3f,%.3f,%.4f,%.2f,%u,%.4f,%.1f,%u,%u\n", t.id,
			        t.x, t.y, t.z_ground, t.dbh_m, t.height_m, t.n_points,
			        t.fit_rmse_m, t.arc_coverage_deg,
			        static_cast<unsigned>(t.n_slices),
			        static_cast<unsigned>(t.quality));
			    os << buf;
		    }
	    });
}

// -------------------------------------------------------- serialization
uint8_t CForestMap::serializeGetVersion() const
{
	return 0;
}

namespace
{
void writeCloud(mrpt::serialization::CArchive& out, const VoxelCloud& c)
{
	out.WriteAs<uint64_t>(c.size());
	c.forEachVoxel(
	    [&](const VoxelKey& k, const VoxelCloud::Accum& a)
	    {
		    out << k.x << k.y << k.z;
		    out << a.sum.x() << a.sum.y() << a.sum.z() << a.count;
	    });
}
void readCloud(mrpt::serialization::CArchive& in, VoxelCloud& c)
{
	const auto n = in.ReadAs<uint64_t>();
	for (uint64_t i = 0; i < n; i++)
	{
		VoxelKey k;
		VoxelCloud::Accum a;
		in >> k.x >> k.y >> k.z >> a.sum.x() >> a.sum.y() >> a.sum.z() >>
		    a.count;
		if (a.count == 0)
			throw std::runtime_error(
			    "CForestMap: corrupt voxel with zero count");
		c.setVoxel(k, a);
	}
}
}  // namespace

void CForestMap::serializeTo(mrpt::serialization::CArchive& out) const
{
	if (!frozen_.empty())
		throw std::logic_error(
		    "CForestMap: serialized with segments apart (call "
		    "transformSegments first)");
	out << opts_.submap_size_m << opts_.edge_voxel_m << opts_.planar_voxel_m
	    << opts_.edge_smoothness_threshold
	    << static_cast<int32_t>(opts_.smoothness_half_window)
	    << opts_.max_insert_range_m << opts_.likelihood_sigma_m
	    << static_cast<int32_t>(opts_.likelihood_decimation);
	out << genericMapParams;
	out.WriteAs<uint64_t>(submaps_.size());
	for (const auto& kv : submaps_)
	{
		out << kv.first.x << kv.first.y << kv.first.z;
		writeCloud(out, kv.second.edge);
		writeCloud(out, kv.second.planar);
	}
	out.WriteAs<uint64_t>(trees_.size());
	for (const auto& t : trees_)
		out << t.id << t.x << t.y << t.z_ground << t.dbh_m << t.height_m
		    << t.n_points << t.fit_rmse_m << t.arc_coverage_deg << t.n_slices
		    << t.quality;
}

void CForestMap::serializeFrom(mrpt::serialization::CArchive& in,
                               uint8_t version)
{
	if (version != 0) MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
	TOptions o;
	int32_t hw, dec;
	in >> o.submap_size_m >> o.edge_voxel_m >> o.planar_voxel_m >>
	    o.edge_smoothness_threshold >> hw >> o.max_insert_range_m >>
	    o.likelihood_sigma_m >> dec;
	o.smoothness_half_window = hw;
	o.likelihood_decimation = dec;
	o.validate();
	in >> genericMapParams;
	opts_ = o;
	submaps_.clear();
	trees_.clear();
	const auto n = in.ReadAs<uint64_t>();
	for (uint64_t i = 0; i < n; i++)
	{
		SubmapKey k;
		in >> k.x >> k.y >> k.z;
		Submap s;
		s.edge.setVoxelSize(static_cast<float>(o.edge_voxel_m));
		s.planar.setVoxelSize(static_cast<float>(o.planar_voxel_m));
		readCloud(in, s.edge);
		readCloud(in, s.planar);
		submaps_.emplace(k, std::move(s));
	}
	const auto nt = in.ReadAs<uint64_t>();
	trees_.resize(nt);
	for (auto& t : trees_)
		in >> t.id >> t.x >> t.y >> t.z_ground >> t.dbh_m >> t.height_m >>
		    t.n_points >> t.fit_rmse_m >> t.arc_coverage_deg >> t.n_slices >>
		    t.quality;
	markDirty();
}

}  // namespace forest_slam::map
