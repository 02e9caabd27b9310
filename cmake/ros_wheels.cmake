# C++ on the pinned ROS wheels' rcl (include()d by the packages that link it: no rclcpp wheel exists).

# The Fast DDS wheel's CMake export names the wheel builder's tinyxml2 (/usr/lib64/libtinyxml2.so), a file
# absent here; libfastrtps itself loads its own copy (ros_*.libs). Drop what does not exist from its interface.
function(drop_absent_fastrtps_links)
  if(TARGET fastrtps)
    get_target_property(_fastrtps_links fastrtps INTERFACE_LINK_LIBRARIES)
    set(_present "")
    foreach(_link IN LISTS _fastrtps_links)
      if(NOT _link MATCHES "^/" OR EXISTS "${_link}")
        list(APPEND _present "${_link}")
      endif()
    endforeach()
    set_target_properties(fastrtps PROPERTIES INTERFACE_LINK_LIBRARIES "${_present}")
  endif()
endfunction()

# The directory an imported library target's file is in (whichever configuration it was exported for).
function(library_dir target out)
  foreach(property IMPORTED_LOCATION_RELEASE IMPORTED_LOCATION_NOCONFIG IMPORTED_LOCATION)
    get_target_property(location ${target} ${property})
    if(location)
      get_filename_component(directory "${location}" DIRECTORY)
      set(${out} "${directory}" PARENT_SCOPE)
      return()
    endif()
  endforeach()
  message(FATAL_ERROR "${target}: no library file found")
endfunction()

# The wheels' libraries find their own dependencies (auditwheel's renamed copies in ros_*.libs) only through
# the loader's path: the directories of the rcl wheel's ros_*.libs, beside the interpreter's packages.
function(ros_libs_dirs out)
  library_dir(rcl::rcl _ros_lib_dir)
  file(GLOB _dirs LIST_DIRECTORIES true "${_ros_lib_dir}/python3.11/site-packages/ros_*.libs")
  set(${out} "${_ros_lib_dir};${_dirs}" PARENT_SCOPE)
endfunction()
