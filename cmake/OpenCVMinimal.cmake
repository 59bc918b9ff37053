# Debian 12 ships OpenCV's CMake config and .pc only with the full libopencv-dev
# (~525 MB).  We need core and imgproc to draw, so we make imported interface
# targets from the -dev packages' headers and libraries.
#
# lpvid_opencv: core + imgproc (drawing).  PNG files are encoded with libpng:
# OpenCV's imgcodecs pulls in ~140 shared libraries (GDAL, GDCM, ...) whose
# relocation costs 0.18 s at every program start (measured with an empty program
# linked against it), a third of the time budget of `lpvid identify` at 1 kHz.
# lpvid_opencv_imgcodecs: for tests that decode the PNGs we write.
find_path(LPVID_OPENCV_INCLUDE opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
find_library(LPVID_OPENCV_CORE opencv_core REQUIRED)
find_library(LPVID_OPENCV_IMGPROC opencv_imgproc REQUIRED)
find_library(LPVID_OPENCV_IMGCODECS opencv_imgcodecs REQUIRED)
find_package(PNG REQUIRED)
add_library(lpvid_opencv INTERFACE)
target_include_directories(lpvid_opencv SYSTEM INTERFACE ${LPVID_OPENCV_INCLUDE})
target_link_libraries(lpvid_opencv INTERFACE ${LPVID_OPENCV_IMGPROC} ${LPVID_OPENCV_CORE} PNG::PNG)
add_library(lpvid_opencv_imgcodecs INTERFACE)
target_link_libraries(lpvid_opencv_imgcodecs INTERFACE ${LPVID_OPENCV_IMGCODECS} lpvid_opencv)
