# Debian 12 ships OpenCV's CMake config and .pc only with the full libopencv-dev
# (~525 MB).  We need core, imgproc and imgcodecs, so we make one imported
# interface target from the three -dev packages' headers and libraries.
find_path(LPVID_OPENCV_INCLUDE opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
find_library(LPVID_OPENCV_CORE opencv_core REQUIRED)
find_library(LPVID_OPENCV_IMGPROC opencv_imgproc REQUIRED)
find_library(LPVID_OPENCV_IMGCODECS opencv_imgcodecs REQUIRED)
add_library(lpvid_opencv INTERFACE)
target_include_directories(lpvid_opencv SYSTEM INTERFACE ${LPVID_OPENCV_INCLUDE})
target_link_libraries(lpvid_opencv INTERFACE
  ${LPVID_OPENCV_IMGCODECS} ${LPVID_OPENCV_IMGPROC} ${LPVID_OPENCV_CORE})
