# The body of each interface package here (ros_interfaces/<name>/CMakeLists.txt), built into the
# venv when no ROS install is sourced (Makefile `venv`): the messages generated with the rosidl
# generators from PyPI, unchanged from the ROS 2 packages of the same name.
find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)
find_package(Python3 REQUIRED COMPONENTS Interpreter Development NumPy)

# gnss_ins_interfaces(MESSAGES <files> DEPENDENCIES <packages>)
macro(gnss_ins_interfaces)
  cmake_parse_arguments(ARG "" "" "MESSAGES;DEPENDENCIES" ${ARGN})
  foreach(dependency IN LISTS ARG_DEPENDENCIES)
    find_package(${dependency} REQUIRED)
  endforeach()
  # The PyPI wheels export the include directories of the machine they were built on; point
  # their Python targets at this interpreter's headers instead.
  get_property(imported DIRECTORY PROPERTY IMPORTED_TARGETS)
  foreach(target IN LISTS imported)
    if(target MATCHES "__rosidl_generator_py$")
      set_target_properties(${target} PROPERTIES
        INTERFACE_INCLUDE_DIRECTORIES "${Python3_INCLUDE_DIRS};${Python3_NumPy_INCLUDE_DIRS}")
    endif()
  endforeach()
  rosidl_generate_interfaces(${PROJECT_NAME} ${ARG_MESSAGES} DEPENDENCIES ${ARG_DEPENDENCIES})
  ament_export_dependencies(rosidl_default_runtime)
  ament_package()
endmacro()
