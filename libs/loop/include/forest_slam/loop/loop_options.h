#pragma once
// [loop]: keyframes, loop detection and verification, pose graph, GNSS
// factors, and the test-bench drift injection (doc/backend.md lists every
// key with its reason).
#include <mrpt/config/CLoadableOptions.h>

#include <string>

namespace forest_slam::loop
{
struct LoopOptions : public mrpt::config::CLoadableOptions
{
	bool enabled = false;
	// Keyframes.
	double keyframe_distance_m = 1.0;
	double keyframe_angle_deg = 15.0;
	double cloud_voxel_m = 0.25;      ///< keyframe cloud voxel filter
	double cloud_max_range_m = 40.0;  ///< keyframe cloud range limit
	// Detection.
	double min_travel_m = 30.0;  ///< candidates: at least this far back
	double search_radius_m = 6.0;
	/** The search radius grows by this fraction of the distance travelled
	 * between the candidate and the current keyframe (odometry drift). */
	double search_drift_fraction = 0.03;
	int max_candidates = 2;  ///< nearest candidates verified per attempt
	int detect_every_keyframes = 3;
	/** After an accepted closure, the next attempt waits this many
	 * keyframes (a closure every few metres is plenty). */
	int closure_spacing_keyframes = 5;
	int submap_keyframes = 8;  ///< keyframes each side in the ICP clouds
	// Place descriptor (Scan Context-style, place_descriptor.h): candidates
	// anywhere in the current estimate, for drift beyond the search radius.
	bool descriptor = true;
	int descriptor_rings = 20;
	int descriptor_sectors = 60;
	double descriptor_radius_m = 20.0;
	/** The descriptor's cloud: the keyframe and this many predecessors. */
	int descriptor_keyframes = 4;
	/** Keyframes whose ring key is nearest are compared in full. */
	int descriptor_retrieval = 10;
	/** Matches farther than this (0 = identical, 1 = unrelated) are not
	 * candidates. */
	double descriptor_max_distance = 0.45;
	/** The best match must be below this times the best match at another
	 * place (else ambiguous: no descriptor candidate). */
	double descriptor_distinct_ratio = 0.9;
	int descriptor_candidates = 1;  ///< best matches verified per attempt
	// Verification (point-to-plane ICP with a Cauchy kernel).
	int icp_iterations = 50;
	/** The current submap (ICP source) is thinned to at most this many
	 * points, evenly along the cloud (0 = all): the cost of every ICP run
	 * and of the uniqueness re-runs scales with it. */
	int icp_max_points = 3000;
	double icp_start_distance_m = 1.5;  ///< correspondence gate, first round
	double icp_final_distance_m = 0.4;  ///< correspondence gate, last round
	double min_overlap = 0.55;          ///< fraction of source points matched
	double max_rmse_m = 0.12;           ///< point-to-plane RMSE of inliers
	/** Information of the weakest direction / matches (each match adds at
	 * most 1): below, the alignment is degenerate (corridor, open field). */
	double min_information_ratio = 0.003;
	/** Mahalanobis gate (chi-square, 6 dof) of the closure's correction
	 * against the drift the odometry can have accumulated. */
	double consistency_chi2 = 16.8;
	/** Threads verifying a candidate (the back-end's own and threads-1
	 * helpers, at its priority): the target's normals and the uniqueness
	 * re-runs are shared out; the closures do not depend on it. */
	int verify_threads = 2;
	// Pose graph noise.
	double odom_sigma_t_m = 0.01;         ///< per edge
	double odom_sigma_t_per_m = 0.02;     ///< per metre of the edge
	double odom_sigma_r_deg = 0.05;       ///< per edge
	double odom_sigma_r_deg_per_m = 0.1;  ///< per metre of the edge
	double loop_sigma_t_m = 0.03;
	double loop_sigma_r_deg = 0.15;
	/** Results of keyframe k are applied when keyframe k + this is made:
	 * the worker runs meanwhile, and the run is deterministic. With 3 the
	 * mapping thread waited 13-19 s of the robot run's ~165 for the
	 * worker, which runs at a low priority (doc/performance.md,
	 * forty-eighth session). */
	int latency_keyframes = 6;
	// GNSS position factors.
	bool gnss_enabled = false;
	int gnss_min_quality = 1;
	double gnss_max_sigma_m = 5.0;      ///< fixes worse than this are not used
	double gnss_gate_sigma = 4.0;       ///< residual beyond: outlier, dropped
	double gnss_min_baseline_m = 15.0;  ///< fixes must span this (heading)
	/** Time constant of the GNSS error [s] (0: white): fixes closer in time
	 * than ~2x this are not independent; their sigmas are inflated. */
	double gnss_correlation_s = 20.0;
	/** At the end of the run, level the map frame with gravity from the
	 * IMU's "up" at every keyframe (levelling.h); not with GNSS (its ENU
	 * frame is levelled already). */
	bool level_with_imu = true;
	// Test bench: odometry drift injected into the odometry (0 = off).
	double inject_yaw_deg_per_m = 0;
	double inject_z_m_per_m = 0;
	double inject_every_m = 2.0;

	void loadFromConfigFile(const mrpt::config::CConfigFileBase& c,
	                        const std::string& section) override;
	void saveToConfigFile(mrpt::config::CConfigFileBase& c,
	                      const std::string& section) const override;
	bool injectsDrift() const
	{
		return inject_yaw_deg_per_m != 0 || inject_z_m_per_m != 0;
	}
};

}  // namespace forest_slam::loop
