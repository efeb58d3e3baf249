"""lapmesh: Laplacian geometry processing on triangle meshes, for numpy arrays.

Meshes are (V, F): V float64 (n, 3) vertex positions, F integer (m, 3) vertex indices, or a
lapmesh.Mesh(V, F) (validated once: pass it in place of (V, F) to skip the arrays' conversion).
Options are keyword arguments with the names and defaults of the ``lapmesh`` command line;
the names a kind accepts are ``lapmesh.names(kind)`` (e.g. ``names("laplacian")``).

    import lapmesh
    V, F = lapmesh.read_mesh("cow.off")
    c = lapmesh.curvatures(V, F, laplacian="cotangent", area="mixed")
    S, M = lapmesh.laplacian(V, F)                 # scipy.sparse CSR stiffness, mass diagonal
    basis = lapmesh.SpectralBasis(V, F, k=30)
    V30 = basis.reconstruct(30)
    V2, report = lapmesh.smooth(V, F, scheme="implicit", lam="auto", iterations=10)
    Vn = lapmesh.add_noise(V, F, level=0.05, seed=7)

Errors: MeshError (ValueError; .element, .index), ParameterError (ValueError; .parameter,
.suggested_value), NumericalError (RuntimeError), IoError (OSError). Warnings are issued as
LapmeshWarning through the warnings module.
"""

from . import _lapmesh
from ._lapmesh import (
    Curvatures,
    IoError,
    LapmeshWarning,
    Mesh,
    MeshError,
    NumericalError,
    ParameterError,
    SpectralBasis,
    add_noise,
    cached_working_memory,
    curvatures,
    denoise_study,
    read_mesh,
    release_working_memory,
    smooth,
    write_mesh,
)

# Shown as lapmesh.MeshError etc. in tracebacks (they are defined in the compiled module).
for _cls in (IoError, LapmeshWarning, MeshError, NumericalError, ParameterError):
    _cls.__module__ = __name__
del _cls

__all__ = [
    "Curvatures", "IoError", "LapmeshWarning", "Mesh", "MeshError", "NumericalError", "ParameterError",
    "SpectralBasis", "add_noise", "cached_working_memory", "curvatures", "denoise_study", "describe", "laplacian",
    "laplacian_arrays", "names", "read_mesh", "release_working_memory", "smooth", "write_mesh",
]


def names(kind):
    """The names an option accepts, in display order: kind is one of 'laplacian', 'area',
    'scheme', 'lambda_unit', 'direction', 'scale', 'status'. Read from the library's tables."""
    try:
        return [name for name, _ in _lapmesh.NAMES[kind]]
    except KeyError:
        raise ValueError("unknown kind %r (expected one of: %s)" % (kind, ", ".join(_lapmesh.NAMES))) from None


def describe(kind):
    """{name: one-line description} of an option's names (as ``lapmesh <cmd> --help`` shows them)."""
    names(kind)
    return dict(_lapmesh.NAMES[kind])


def laplacian_arrays(V, F=None, **options):
    """The Laplacian pencil without scipy: (data, indices, indptr, n, mass), the stiffness S
    in CSR arrays (n x n, symmetric, negative semidefinite; indices and indptr int32, the
    assembly's own arrays, not copies) and the diagonal of the mass M. Options as laplacian()."""
    return _lapmesh._laplacian_csr(V, F, **options)


def laplacian(V, F=None, **options):
    """(S, M): the stiffness S as a scipy.sparse.csr_matrix (n x n, symmetric, rows summing to 0,
    negative semidefinite) and the mass diagonal M as a numpy array (the vertex areas for the
    cotangent Laplacian, the degrees for the uniform one). L = M^-1 S.

    Keyword options: laplacian, area, mollification (as curvatures()). Needs scipy (Debian: python3-scipy);
    laplacian_arrays() gives the same matrix as CSR arrays without it."""
    try:
        import scipy.sparse
    except ImportError as e:
        raise ImportError("lapmesh.laplacian needs scipy (Debian: apt install python3-scipy; "
                          "lapmesh.laplacian_arrays gives the CSR arrays without it)") from e
    data, indices, indptr, n, mass = _lapmesh._laplacian_csr(V, F, **options)
    return scipy.sparse.csr_matrix((data, indices, indptr), shape=(n, n)), mass

