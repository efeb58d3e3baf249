# ctest python_install: `cmake --install` into a fresh prefix, then the installed package imports
# (from outside the build tree) and computes.
file(REMOVE_RECURSE "${WORK_DIR}")
execute_process(COMMAND ${CMAKE_COMMAND} --install "${BINARY_DIR}" --prefix "${WORK_DIR}/prefix"
                OUTPUT_QUIET RESULT_VARIABLE rc)
if(rc)
  message(FATAL_ERROR "cmake --install failed")
endif()
set(ENV{PYTHONPATH} "${WORK_DIR}/prefix/${INSTALL_DIR}")
execute_process(
  COMMAND ${PYTHON} -c "import lapmesh, os
assert lapmesh.__file__.startswith(os.environ['PYTHONPATH']), lapmesh.__file__
assert os.path.exists(os.path.join(os.path.dirname(lapmesh.__file__), '__init__.pyi'))
V, F = lapmesh.read_mesh('${MESH}')
print('installed lapmesh:', lapmesh.__file__, lapmesh.curvatures(V, F).mean.shape)"
  WORKING_DIRECTORY "${WORK_DIR}" RESULT_VARIABLE rc)
if(rc)
  message(FATAL_ERROR "the installed package does not work")
endif()
