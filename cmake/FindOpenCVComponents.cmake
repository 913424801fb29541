# Finds the OpenCV modules genscene uses (core, imgproc, imgcodecs) and defines the imported
# target OpenCV::components. Debian's per-module -dev packages ship no CMake config (only the
# heavy libopencv-dev metapackage does), so we look for the headers and libraries directly and
# use the config when it is there.
find_package(OpenCV QUIET COMPONENTS core imgproc imgcodecs)
if(OpenCV_FOUND)
  add_library(OpenCV::components INTERFACE IMPORTED)
  set_target_properties(OpenCV::components PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${OpenCV_INCLUDE_DIRS}"
    INTERFACE_LINK_LIBRARIES "opencv_core;opencv_imgproc;opencv_imgcodecs")
  set(OpenCVComponents_FOUND TRUE)
  return()
endif()

find_path(OpenCVComponents_INCLUDE_DIR opencv2/core.hpp PATH_SUFFIXES opencv4)
foreach(module core imgproc imgcodecs)
  find_library(OpenCVComponents_${module}_LIBRARY NAMES opencv_${module})
  list(APPEND OpenCVComponents_LIBRARIES ${OpenCVComponents_${module}_LIBRARY})
  list(APPEND _opencv_required OpenCVComponents_${module}_LIBRARY)
endforeach()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenCVComponents
  REQUIRED_VARS OpenCVComponents_INCLUDE_DIR ${_opencv_required})

if(OpenCVComponents_FOUND AND NOT TARGET OpenCV::components)
  add_library(OpenCV::components INTERFACE IMPORTED)
  set_target_properties(OpenCV::components PROPERTIES
    INTERFACE_INCLUDE_DIRECTORIES "${OpenCVComponents_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${OpenCVComponents_LIBRARIES}")
endif()
