"""Borrowed array views for the hot kernels: the same data, no reference counting.

Numba counts references to every array with atomic instructions: at each function entry
(for each array argument), at each view (``a[i]``) and at each variable's death. The
refcount pruning pass removes only simple patterns, so in the exact engine's event loop,
where small functions take dozens of arrays and are called millions of times, these
atomic operations cost about a third of the run (measured in docs/impact-cost.md).

:func:`borrow` returns a view of an array whose memory-management pointer is null: every
reference count on it, and on every view made from it, is then a null test. It is safe only
for arrays that something else keeps alive for as long as the view is used (the caller's
NumPy arrays during a kernel call, or arrays allocated by the calling kernel) and that are
never returned or stored: the kernels here obey both rules. The NumPy twin is the identity.
"""
from __future__ import annotations

from numba import config, types
from numba.extending import intrinsic
from numba.np.arrayobj import populate_array


def borrow_py(array):
    """The array itself (the NumPy twin of :func:`borrow`)."""
    return array


@intrinsic
def _borrow(typingctx, array):
    if not isinstance(array, types.Array):
        return None

    def codegen(context, builder, signature, args):
        source = context.make_array(array)(context, builder, value=args[0])
        view = context.make_array(array)(context, builder)
        populate_array(view, data=source.data, shape=source.shape, strides=source.strides,
                       itemsize=source.itemsize, meminfo=None, parent=None)
        return view._getvalue()

    return array(array), codegen


# under NUMBA_DISABLE_JIT the kernels run as plain Python, where an intrinsic cannot be called
borrow = borrow_py if config.DISABLE_JIT else _borrow
