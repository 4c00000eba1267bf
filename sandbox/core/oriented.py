"""`data_oriented`: Taichi's `ti.data_oriented` with a fast attribute lookup.

`ti.data_oriented` replaces the class's `__getattribute__` with a Python function so that a kernel method read
through an instance comes back bound to it. That function runs for every attribute read on the instance, kernels or
not (`self.dt`, `self.particles`, and the `isinstance` checks Taichi itself makes on `self` when it launches a kernel
method: ten reads per launch), at about 1.5 us each. A kernel method then costs 30-36 us to launch against 16 us for
a free kernel, and a small scene's step spent more time in these reads than in its kernels.

Here the class is decorated by Taichi as usual, and its `__getattribute__` is then wrapped so that only the names of
the class's kernel methods go through Taichi's lookup; every other name is read the ordinary way. Where Taichi does
not install its own lookup, or is a version taichi_compat does not know, the class is left as Taichi made it.
"""

import taichi as ti

from . import taichi_compat


def _kernel_names(cls) -> frozenset[str]:
    """Names in cls and its bases that hold a Taichi kernel (as a function or a property's getter)."""
    names = set()
    for klass in cls.__mro__:
        for name, value in vars(klass).items():
            target = value.fget if isinstance(value, property) else value
            if taichi_compat.is_kernel(target):
                names.add(name)
    return frozenset(names)


def data_oriented(cls):
    """Class decorator: ti.data_oriented(cls), with plain attribute reads for every name that is not a kernel."""
    cls = ti.data_oriented(cls)
    taichi_lookup = taichi_compat.data_oriented_lookup(cls)
    if taichi_lookup is None:
        return cls
    kernels_of: dict[type, frozenset[str]] = {}  # per concrete class: subclasses may add kernel methods
    plain = object.__getattribute__

    def __getattribute__(self, item):
        kind = type(self)
        kernels = kernels_of.get(kind)
        if kernels is None:
            kernels = kernels_of[kind] = _kernel_names(kind)
        if item in kernels:
            return taichi_lookup(self, item)
        return plain(self, item)

    cls.__getattribute__ = __getattribute__
    return cls
