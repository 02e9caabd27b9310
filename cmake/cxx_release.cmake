# The C++ packages' common settings (include()d by src/*/CMakeLists.txt): C++17, a Release build unless
# CMAKE_BUILD_TYPE says otherwise.
set(CMAKE_CXX_STANDARD 17)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
if(NOT CMAKE_BUILD_TYPE)
  set(CMAKE_BUILD_TYPE Release)
endif()
# Never -march=native: Eigen's layout would then differ from the prebuilt libpinocchio's.
