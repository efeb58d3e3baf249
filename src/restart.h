// The command line's restart with settings that only a new process takes up.
//
// Two libraries read their settings from the environment once, when they load: glibc its
// tunables (huge pages for large buffers, huge_pages.h) and OpenBLAS built with DYNAMIC_ARCH the
// core whose kernels it runs. Where either would help, the program restarts itself once, with
// the same arguments, before it does anything else.
#ifndef LAPMESH_SRC_RESTART_H
#define LAPMESH_SRC_RESTART_H

namespace lapmesh_cli {

/// Whether the subcommand named in `argv` can factorise a matrix (spectrum, reconstruct, smooth,
/// denoise-study, view), where the BLAS's kernels matter.
bool subcommand_uses_the_blas(int argc, char** argv);

/// Restarts the program with
///  - glibc.malloc.hugetlb=1 added to GLIBC_TUNABLES when huge_pages_restart_wanted();
///  - OPENBLAS_CORETYPE=lapmesh::openblas_coretype_that_fits() when OpenBLAS runs kernels without
///    AVX2 on a CPU with AVX2, the subcommand uses the BLAS and the variable is unset (a value
///    the user set is kept; the subcommand then warns, lapmesh::blas_core_warning()).
/// Returns, changing nothing, when neither applies or when the restart fails.
void restart_if_useful(int argc, char** argv);

} // namespace lapmesh_cli

#endif
