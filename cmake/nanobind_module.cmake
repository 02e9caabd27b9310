# A package's nanobind module (include()d by its CMakeLists.txt after ament_cmake_python): nanobind as the
# venv's wheel has it, and the module installed with its type stubs.
find_package(Python 3.11 COMPONENTS Interpreter Development.Module REQUIRED)
execute_process(
  COMMAND "${Python_EXECUTABLE}" -m nanobind --cmake_dir
  OUTPUT_STRIP_TRAILING_WHITESPACE OUTPUT_VARIABLE nanobind_ROOT)
find_package(nanobind CONFIG REQUIRED)

# Install ``target`` (a nanobind module) into the package's Python directory beside the package's Python
# sources, with the .pyi nanobind's stub generator writes from the built module (mypy checks every call
# into it against them; py.typed in the package marks it typed).
function(install_nanobind_module target)
  nanobind_add_stub(
    ${target}_stub MODULE ${target} OUTPUT ${target}.pyi PYTHON_PATH $<TARGET_FILE_DIR:${target}> DEPENDS ${target})
  ament_python_install_package(${PROJECT_NAME})
  install(TARGETS ${target} LIBRARY DESTINATION "${PYTHON_INSTALL_DIR}/${PROJECT_NAME}")
  install(FILES "${CMAKE_CURRENT_BINARY_DIR}/${target}.pyi" DESTINATION "${PYTHON_INSTALL_DIR}/${PROJECT_NAME}")
endfunction()
