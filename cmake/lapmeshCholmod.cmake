# lapmesh_add_cholmod_target(<name> [IMPORTED] [ALWAYS] [LINK <targets>...])
#
# Finds SuiteSparse CHOLMOD and the BLAS it runs on, and creates the INTERFACE library <name>
# with their usage requirements: LAPMESH_HAS_CHOLMOD (the implicit smoothing defaults to CHOLMOD's
# supernodal Cholesky, the spectral solver offers it) and, with a BLAS, LAPMESH_HAS_BLAS (the block
# Lanczos's tall matrix products go to dgemm, internal/block_lanczos.h). <name> also links
# <targets>. Shared by the build (lapmesh_cholmod) and the installed package (lapmesh::cholmod,
# IMPORTED). Without CHOLMOD the target is created only with ALWAYS, and is then only <targets>:
# the headers work without CHOLMOD. Sets LAPMESH_CHOLMOD_FOUND and LAPMESH_BLAS_FOUND in the caller.
function(lapmesh_add_cholmod_target name)
  cmake_parse_arguments(arg "IMPORTED;ALWAYS" "" "LINK" ${ARGN})
  find_library(LAPMESH_CHOLMOD_LIBRARY cholmod)
  find_path(LAPMESH_CHOLMOD_INCLUDE cholmod.h PATH_SUFFIXES suitesparse)
  set(found FALSE)
  if(LAPMESH_CHOLMOD_LIBRARY AND LAPMESH_CHOLMOD_INCLUDE)
    set(found TRUE)
  endif()
  set(LAPMESH_CHOLMOD_FOUND ${found} PARENT_SCOPE)
  set(LAPMESH_BLAS_FOUND FALSE PARENT_SCOPE)
  if(NOT found AND NOT arg_ALWAYS)
    return()
  endif()
  if(arg_IMPORTED)
    add_library(${name} INTERFACE IMPORTED)
  else()
    add_library(${name} INTERFACE)
  endif()
  target_link_libraries(${name} INTERFACE ${arg_LINK})
  if(NOT found)
    return()
  endif()
  target_compile_definitions(${name} INTERFACE LAPMESH_HAS_CHOLMOD)
  target_include_directories(${name} INTERFACE "${LAPMESH_CHOLMOD_INCLUDE}")
  # (dlsym: internal/cholmod.h finds the OpenMP runtime CHOLMOD loads; libc has it from glibc 2.34)
  target_link_libraries(${name} INTERFACE "${LAPMESH_CHOLMOD_LIBRARY}" ${CMAKE_DL_LIBS})
  # Debian: OpenBLAS through libblas.so, the BLAS CHOLMOD itself runs on.
  find_package(BLAS QUIET)
  if(BLAS_FOUND)
    target_compile_definitions(${name} INTERFACE LAPMESH_HAS_BLAS)
    target_link_libraries(${name} INTERFACE ${BLAS_LIBRARIES})
    set(LAPMESH_BLAS_FOUND TRUE PARENT_SCOPE)
  endif()
endfunction()
