# Finds the OpenCV modules genscene uses and defines two imported targets:
#   OpenCV::components  core, imgproc, imgcodecs (images, undistortion, drawing);
#   OpenCV::features    features2d, calib3d, flann (ORB features and PnP for fusion's feature tracking).
# Debian's per-module -dev packages ship no CMake config (only the heavy libopencv-dev metapackage
# does), so we look for the headers and libraries directly and use the config when it is there.
set(_opencv_image_modules core imgproc imgcodecs)
set(_opencv_feature_modules features2d calib3d flann)

find_package(OpenCV QUIET COMPONENTS ${_opencv_image_modules} ${_opencv_feature_modules})
if(OpenCV_FOUND)
  if(NOT TARGET OpenCV::components)
    add_library(OpenCV::components INTERFACE IMPORTED)
    set_target_properties(OpenCV::components PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${OpenCV_INCLUDE_DIRS}"
      INTERFACE_LINK_LIBRARIES "opencv_core;opencv_imgproc;opencv_imgcodecs")
    add_library(OpenCV::features INTERFACE IMPORTED)
    set_target_properties(OpenCV::features PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${OpenCV_INCLUDE_DIRS}"
      INTERFACE_LINK_LIBRARIES "opencv_features2d;opencv_calib3d;opencv_flann;opencv_core;opencv_imgproc")
  endif()
  set(OpenCVComponents_FOUND TRUE)
  return()
endif()

find_path(OpenCVComponents_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
set(_opencv_required)
foreach(module ${_opencv_image_modules} ${_opencv_feature_modules})
  find_library(OpenCVComponents_${module}_LIBRARY NAMES opencv_${module})
  list(APPEND _opencv_required OpenCVComponents_${module}_LIBRARY)
endforeach()
set(OpenCVComponents_LIBRARIES)
foreach(module ${_opencv_image_modules})
  list(APPEND OpenCVComponents_LIBRARIES ${OpenCVComponents_${module}_LIBRARY})
endforeach()
set(OpenCVComponents_FEATURE_LIBRARIES)
foreach(module ${_opencv_feature_modules} core imgproc)
  list(APPEND OpenCVComponents_FEATURE_LIBRARIES ${OpenCVComponents_${module}_LIBRARY})
endforeach()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenCVComponents
  REQUIRED_VARS OpenCVComponents_INCLUDE_DIR ${_opencv_required})

if(OpenCVComponents_FOUND AND NOT TARGET OpenCV::components)
  add_library(OpenCV::components INTERFACE IMPORTED)
  set_target_properties(OpenCV::components PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${OpenCVComponents_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${OpenCVComponents_LIBRARIES}")
  add_library(OpenCV::features INTERFACE IMPORTED)
  set_target_properties(OpenCV::features PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${OpenCVComponents_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${OpenCVComponents_FEATURE_LIBRARIES}")
endif()
