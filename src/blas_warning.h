// The command line's report of a slow BLAS (lapmesh::blas_core_warning()).
#ifndef LAPMESH_SRC_BLAS_WARNING_H
#define LAPMESH_SRC_BLAS_WARNING_H

namespace lapmesh_cli {

/// When `applies` (the run factorises: spectral or implicit), prints lapmesh::blas_core_warning()
/// as one line on stderr, "lapmesh: warning: ...", at most once per process.
void warn_if_slow_blas(bool applies = true);

} // namespace lapmesh_cli

#endif
