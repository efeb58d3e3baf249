#include "blas_warning.h"

#include <lapmesh/blas.h>

#include <iostream>

namespace lapmesh_cli {

void warn_if_slow_blas(bool applies)
{
  static bool warned = false;
  if(!applies || warned) return;
  warned = true;
  if(const auto text = lapmesh::blas_core_warning()) std::cerr << "lapmesh: warning: " << *text << '\n';
}

} // namespace lapmesh_cli
