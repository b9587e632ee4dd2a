# Every external dependency, found from Debian 12 packages (scripts/setup installs them).
# Libraries that ship CMake config files are found with find_package; SuiteSparse 5.12 (Debian 12)
# and Ipopt ship none/pkg-config only, so they get imported targets here.

find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(Threads REQUIRED)

if(SINEW_BUILD_RT OR SINEW_BUILD_TOOLS)
  find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs videoio features2d calib3d)
endif()

if(SINEW_BUILD_OFFLINE)
  find_package(PkgConfig REQUIRED)
  pkg_check_modules(IPOPT REQUIRED IMPORTED_TARGET ipopt)
  find_package(NLopt REQUIRED)
  find_package(CGAL REQUIRED)
  find_package(ZLIB REQUIRED)  # offline/io: gzip-compressed NIfTI / INRIA images
  find_package(fmt REQUIRED)  # offline/registration: progress messages
  # CHOLMOD (SuiteSparse) on OpenBLAS: Debian switches the BLAS/LAPACK alternatives to OpenBLAS
  # once libopenblas-dev is installed; we still link it explicitly so the choice is visible.
  find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
  find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
  find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig REQUIRED)
  find_library(OPENBLAS_LIBRARY openblas REQUIRED)
  add_library(sinew_cholmod INTERFACE)
  set_target_properties(sinew_cholmod PROPERTIES EXPORT_NAME cholmod)
  target_include_directories(sinew_cholmod SYSTEM INTERFACE ${CHOLMOD_INCLUDE_DIR})
  target_link_libraries(sinew_cholmod INTERFACE ${CHOLMOD_LIBRARY} ${SUITESPARSECONFIG_LIBRARY}
                                                ${OPENBLAS_LIBRARY})
endif()

if(SINEW_BUILD_TOOLS)
  find_package(nlohmann_json 3 REQUIRED)
  find_package(CLI11 REQUIRED)
  find_package(fmt REQUIRED)
  # sinew-track --hdf5: whisker tables for h5py/pandas. By pkg-config: CMake's FindHDF5 needs the C
  # language enabled.
  find_package(PkgConfig REQUIRED)
  pkg_check_modules(HDF5 REQUIRED IMPORTED_TARGET hdf5)
endif()

if(SINEW_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()

if(SINEW_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()
