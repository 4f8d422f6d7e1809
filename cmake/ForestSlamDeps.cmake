# Third-party libraries, all from Debian 12 packages (scripts/install-deps.sh).
find_package(Threads REQUIRED)
find_package(Eigen3 REQUIRED NO_MODULE)
find_package(ZLIB REQUIRED)
find_package(mrpt-core REQUIRED)
find_package(mrpt-system REQUIRED)
find_package(mrpt-config REQUIRED)
find_package(mrpt-io REQUIRED)
find_package(mrpt-serialization REQUIRED)
find_package(mrpt-poses REQUIRED)
find_package(mrpt-obs REQUIRED)
find_package(mrpt-maps REQUIRED)
find_package(mrpt-topography REQUIRED)
find_package(nanoflann REQUIRED)
find_package(GTest REQUIRED)
# PCL, Ceres and OctoMap are looked up by the modules that need them
# (see ForestSlamHelpers.cmake: forest_slam_find_pcl etc.) so a module that
# does not use them does not pay for their configuration.
