"""Eight-column steps of the Canny passes as Numba intrinsics emitting LLVM vector code.

A pass over a band is a few hundred short rows (~40-60 columns on the rig). Written as a plain loop per row, LLVM
vectorises it but guards each vector loop with run-time alias checks between every pair of planes (Numba cannot
mark arrays as not aliasing), a minimum trip count of 16 below which the row runs scalar, and a scalar remainder:
~60-75 ns per row and pass, half the edge stage. These intrinsics do one 8-column step with explicit
``<8 x float>`` loads and stores instead, so that a row is a plain loop of whole steps: no checks, no remainder.
Every step computes exactly the float32 operations, in the same order, of the scalar expression it replaces (no
fused multiply-add, no reassociation): the results are bit-identical to the loop versions in `canny`.

Without JIT (``NUMBA_DISABLE_JIT=1``) each is a plain Python function doing the same arithmetic column by column.

Note: a kernel's on-disk cache does not notice edits to this file; clear ``__pycache__`` after changing it.
"""

from __future__ import annotations

from typing import Any, Final

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

LANES: Final = 8
"""Columns per step (one AVX2 register of float32)."""

_F32: Final = ir.FloatType()
_V8: Final = ir.VectorType(ir.FloatType(), LANES)


def _vec_ptr(context: Any, builder: Any, array_type: Any, array: Any, index: Any, index_type: Any) -> Any:
    """Return a ``<8 x float>*`` to ``array[index]`` (a 1-D float32 array, index in elements)."""
    data = context.make_array(array_type)(context, builder, array).data
    pointer = builder.gep(data, [context.cast(builder, index, index_type, types.intp)])
    return builder.bitcast(pointer, _V8.as_pointer())


def _load(builder: Any, pointer: Any) -> Any:
    return builder.load(pointer, align=4)


def _offset(builder: Any, pointer: Any, lanes: int) -> Any:
    """Return `pointer` (``<8 x float>*``) moved by `lanes` float32 elements."""
    scalar = builder.bitcast(pointer, _F32.as_pointer())
    return builder.bitcast(builder.gep(scalar, [ir.Constant(ir.IntType(64), lanes)]), _V8.as_pointer())


def _splat(value: float) -> Any:
    return ir.Constant(_V8, [value] * LANES)


def _sqrt(builder: Any, value: Any) -> Any:
    function = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V8, [_V8]), "llvm.sqrt.v8f32")
    return builder.call(function, [value])


def _is_f4_1d(array: Any) -> bool:
    return isinstance(array, types.Array) and array.ndim == 1 and array.dtype == types.float32


def _sobel8_python(smo: Any, a: Any, b: Any, d: Any, ogx: Any, ogy: Any, omag: Any) -> None:
    two = np.float32(2.0)
    for i in range(LANES):
        a_i, b_i, d_i = int(a) + i, int(b) + i, int(d) + i
        gx = (smo[a_i + 1] + two * smo[b_i + 1] + smo[d_i + 1]) - (smo[a_i - 1] + two * smo[b_i - 1] + smo[d_i - 1])
        gy = (smo[d_i - 1] + two * smo[d_i] + smo[d_i + 1]) - (smo[a_i - 1] + two * smo[a_i] + smo[a_i + 1])
        ogx[b_i] = gx
        ogy[b_i] = gy
        omag[b_i] = np.sqrt(gx * gx + gy * gy)


def _sobel8_intrinsic() -> Any:
    if numba.config.DISABLE_JIT:
        return _sobel8_python

    @intrinsic
    def sobel8(typingctx: Any, smo: Any, a: Any, b: Any, d: Any, ogx: Any, ogy: Any, omag: Any) -> Any:
        if not all(_is_f4_1d(x) for x in (smo, ogx, ogy, omag)):
            return None
        if not all(isinstance(x, types.Integer) for x in (a, b, d)):
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            smo_t, a_t, b_t, d_t, gx_t, gy_t, mag_t = signature.args
            pa = _vec_ptr(context, builder, smo_t, args[0], args[1], a_t)
            pb = _vec_ptr(context, builder, smo_t, args[0], args[2], b_t)
            pd = _vec_ptr(context, builder, smo_t, args[0], args[3], d_t)
            a_m, a_0, a_p = (_load(builder, _offset(builder, pa, k)) for k in (-1, 0, 1))
            b_m, b_p = (_load(builder, _offset(builder, pb, k)) for k in (-1, 1))
            d_m, d_0, d_p = (_load(builder, _offset(builder, pd, k)) for k in (-1, 0, 1))
            two = _splat(2.0)
            # gx = (a[+1] + 2 b[+1] + d[+1]) - (a[-1] + 2 b[-1] + d[-1]), left to right as in Python.
            right = builder.fadd(builder.fadd(a_p, builder.fmul(two, b_p)), d_p)
            left = builder.fadd(builder.fadd(a_m, builder.fmul(two, b_m)), d_m)
            gx = builder.fsub(right, left)
            # gy = (d[-1] + 2 d[0] + d[+1]) - (a[-1] + 2 a[0] + a[+1]).
            down = builder.fadd(builder.fadd(d_m, builder.fmul(two, d_0)), d_p)
            up = builder.fadd(builder.fadd(a_m, builder.fmul(two, a_0)), a_p)
            gy = builder.fsub(down, up)
            mag = _sqrt(builder, builder.fadd(builder.fmul(gx, gx), builder.fmul(gy, gy)))
            for value, array, array_t in ((gx, args[4], gx_t), (gy, args[5], gy_t), (mag, args[6], mag_t)):
                builder.store(value, _vec_ptr(context, builder, array_t, array, args[2], b_t), align=4)
            return context.get_dummy_value()

        return types.void(smo, a, b, d, ogx, ogy, omag), codegen

    return sobel8


sobel8: Final = _sobel8_intrinsic()
"""``sobel8(smo, a, b, d, ogx, ogy, omag)``: the 3x3 Sobel gradients and their L2 norm of the flat plane `smo`
at the 8 flat indices ``b .. b + 7`` (`a`, `d`: the same columns one row up and down), written to `ogx`, `ogy`,
`omag` at ``b .. b + 7``; every column read (``b - 1 .. b + 8`` and the same up and down) must be in the plane."""


def _splat_value(builder: Any, value: Any) -> Any:
    """Return a ``<8 x float>`` holding the float32 `value` in every lane."""
    one = builder.insert_element(ir.Constant(_V8, ir.Undefined), value, ir.Constant(ir.IntType(32), 0))
    return builder.shuffle_vector(
        one, ir.Constant(_V8, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), LANES), [0] * LANES)
    )


def _weighted5(builder: Any, w0: Any, w1: Any, w2: Any, m2: Any, m1: Any, c: Any, p1: Any, p2: Any) -> Any:
    """``w0 * (m2 + p2) + w1 * (m1 + p1) + w2 * c``, evaluated as Python does (left to right)."""
    outer = builder.fadd(builder.fmul(w0, builder.fadd(m2, p2)), builder.fmul(w1, builder.fadd(m1, p1)))
    return builder.fadd(outer, builder.fmul(w2, c))


def _is_u1_1d(array: Any) -> bool:
    return isinstance(array, types.Array) and array.ndim == 1 and array.dtype == types.uint8


def _hsmooth8_python(f: Any, k: Any, w0: Any, w1: Any, w2: Any, tmp: Any, out: Any) -> None:
    for i in range(LANES):
        j = int(k) + i
        t = w0 * (np.float32(f[j - 2]) + np.float32(f[j + 2])) + w1 * (np.float32(f[j - 1]) + np.float32(f[j + 1]))
        t += w2 * np.float32(f[j])
        tmp[int(out) + i] = t


def _hsmooth8_intrinsic() -> Any:
    if numba.config.DISABLE_JIT:
        return _hsmooth8_python

    @intrinsic
    def hsmooth8(typingctx: Any, f: Any, k: Any, w0: Any, w1: Any, w2: Any, tmp: Any, out: Any) -> Any:
        if not (_is_u1_1d(f) and _is_f4_1d(tmp) and isinstance(k, types.Integer) and isinstance(out, types.Integer)):
            return None
        if not all(w == types.float32 for w in (w0, w1, w2)):
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            f_t, k_t, _, _, _, tmp_t, out_t = signature.args
            data = context.make_array(f_t)(context, builder, args[0]).data
            index = context.cast(builder, args[1], k_t, types.intp)
            v8i8 = ir.VectorType(ir.IntType(8), LANES)
            taps = []
            for offset in (-2, -1, 0, 1, 2):
                at = builder.add(index, ir.Constant(ir.IntType(64), offset))
                pointer = builder.bitcast(builder.gep(data, [at]), v8i8.as_pointer())
                taps.append(builder.uitofp(builder.load(pointer, align=1), _V8))
            w0v, w1v, w2v = (_splat_value(builder, w) for w in args[2:5])
            value = _weighted5(builder, w0v, w1v, w2v, *taps)
            builder.store(value, _vec_ptr(context, builder, tmp_t, args[5], args[6], out_t), align=4)
            return context.get_dummy_value()

        return types.void(f, k, w0, w1, w2, tmp, out), codegen

    return hsmooth8


hsmooth8: Final = _hsmooth8_intrinsic()
"""``hsmooth8(f, k, w0, w1, w2, tmp, out)``: the 5-tap horizontal smoothing (weights ``w0 w1 w2 w1 w0``) of the
flat uint8 image `f` at the flat indices ``k .. k + 7``, written to ``tmp[out .. out + 7]``; ``f[k - 2 .. k + 9]``
are read (all in the row)."""


def _vsmooth8_python(
    t: Any, ka: Any, kb: Any, kc: Any, kd: Any, ke: Any, w0: Any, w1: Any, w2: Any, smo: Any, out: Any
) -> None:
    for i in range(LANES):
        smo[int(out) + i] = (
            w0 * (t[int(ka) + i] + t[int(ke) + i]) + w1 * (t[int(kb) + i] + t[int(kd) + i]) + w2 * t[int(kc) + i]
        )


def _vsmooth8_intrinsic() -> Any:
    if numba.config.DISABLE_JIT:
        return _vsmooth8_python

    @intrinsic
    def vsmooth8(
        typingctx: Any,
        t: Any,
        ka: Any,
        kb: Any,
        kc: Any,
        kd: Any,
        ke: Any,
        w0: Any,
        w1: Any,
        w2: Any,
        smo: Any,
        out: Any,
    ) -> Any:
        indices = (ka, kb, kc, kd, ke, out)
        if not (_is_f4_1d(t) and _is_f4_1d(smo)) or not all(isinstance(x, types.Integer) for x in indices):
            return None
        if not all(w == types.float32 for w in (w0, w1, w2)):
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            t_t = signature.args[0]
            rows = [
                _load(builder, _vec_ptr(context, builder, t_t, args[0], args[i], signature.args[i]))
                for i in range(1, 6)
            ]
            w0v, w1v, w2v = (_splat_value(builder, w) for w in args[6:9])
            value = _weighted5(builder, w0v, w1v, w2v, rows[0], rows[1], rows[2], rows[3], rows[4])
            smo_t = signature.args[9]
            builder.store(value, _vec_ptr(context, builder, smo_t, args[9], args[10], signature.args[10]), align=4)
            return context.get_dummy_value()

        return types.void(t, ka, kb, kc, kd, ke, w0, w1, w2, smo, out), codegen

    return vsmooth8


vsmooth8: Final = _vsmooth8_intrinsic()
"""``vsmooth8(t, ka, kb, kc, kd, ke, w0, w1, w2, smo, out)``: the 5-tap vertical smoothing (weights
``w0 w1 w2 w1 w0``) of the flat plane `t` from the 8 columns at ``ka``, ``kb``, ``kc``, ``kd``, ``ke`` (rows
r - 2 .. r + 2), written to ``smo[out .. out + 7]``."""


TAN_22_5_F32: Final = np.float32(0.41421356237309503)
TAN_67_5_F32: Final = np.float32(TAN_22_5_F32 + np.float32(2.0))
"""``TAN_22_5 + TWO`` as float32, the value the scalar suppression compares with."""


def _nms8_python(
    mag: Any, gx: Any, gy: Any, k: Any, width: Any, first: Any, last: Any, zfirst: Any, zlast: Any, low: Any,
    high: Any, edges: Any,
) -> int:  # fmt: skip
    strong = 0
    w = int(width)
    for i in range(LANES):
        j = int(k) + i
        m = mag[j]
        ax = abs(gx[j])
        ay = abs(gy[j])
        horizontal = ay < ax * TAN_22_5_F32
        vertical = ay > ax * TAN_67_5_F32
        falling = gx[j] * gy[j] < 0
        diag_a = mag[j - w + 1] if falling else mag[j - w - 1]
        diag_b = mag[j + w - 1] if falling else mag[j + w + 1]
        a = mag[j - 1] if horizontal else (mag[j - w] if vertical else diag_a)
        b = mag[j + 1] if horizontal else (mag[j + w] if vertical else diag_b)
        diagonal = not (horizontal or vertical)
        keep = (m > low) and (m > a) and ((m > b) or ((m == b) and not diagonal))
        label = (2 if m > high else 1) if keep else 0
        if first <= i <= last:
            edges[j] = label
            strong |= (label == 2) << i
        elif zfirst <= i <= zlast:
            edges[j] = 0
    return strong


def _nms8_intrinsic() -> Any:
    if numba.config.DISABLE_JIT:
        return _nms8_python

    @intrinsic
    def nms8(
        typingctx: Any, mag: Any, gx: Any, gy: Any, k: Any, width: Any, first: Any, last: Any, zfirst: Any,
        zlast: Any, low: Any, high: Any, edges: Any,
    ) -> Any:  # fmt: skip
        if not all(_is_f4_1d(x) for x in (mag, gx, gy)) or not _is_u1_1d(edges):
            return None
        if not all(isinstance(x, types.Integer) for x in (k, width, first, last, zfirst, zlast)):
            return None
        if low != types.float32 or high != types.float32:
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            mag_t, gx_t, gy_t, k_t, width_t, first_t, last_t, zfirst_t, zlast_t, _, _, edges_t = signature.args
            i64 = ir.IntType(64)
            index = context.cast(builder, args[3], k_t, types.intp)
            w = context.cast(builder, args[4], width_t, types.intp)
            mag_data = context.make_array(mag_t)(context, builder, args[0]).data

            def mag_at(offset: Any) -> Any:
                pointer = builder.gep(mag_data, [builder.add(index, offset)])
                return builder.load(builder.bitcast(pointer, _V8.as_pointer()), align=4)

            zero = ir.Constant(i64, 0)
            one = ir.Constant(i64, 1)
            minus_w = builder.neg(w)
            m = mag_at(zero)
            gxv = _load(builder, _vec_ptr(context, builder, gx_t, args[1], args[3], k_t))
            gyv = _load(builder, _vec_ptr(context, builder, gy_t, args[2], args[3], k_t))
            fabs = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V8, [_V8]), "llvm.fabs.v8f32")
            ax = builder.call(fabs, [gxv])
            ay = builder.call(fabs, [gyv])
            horizontal = builder.fcmp_ordered("<", ay, builder.fmul(ax, _splat(float(TAN_22_5_F32))))
            vertical = builder.fcmp_ordered(">", ay, builder.fmul(ax, _splat(float(TAN_67_5_F32))))
            falling = builder.fcmp_ordered("<", builder.fmul(gxv, gyv), _splat(0.0))
            up_left = mag_at(builder.sub(minus_w, one))
            up = mag_at(minus_w)
            up_right = mag_at(builder.add(minus_w, one))
            left = mag_at(ir.Constant(i64, -1))
            right = mag_at(one)
            down_left = mag_at(builder.sub(w, one))
            down = mag_at(w)
            down_right = mag_at(builder.add(w, one))
            diag_a = builder.select(falling, up_right, up_left)
            diag_b = builder.select(falling, down_left, down_right)
            a = builder.select(horizontal, left, builder.select(vertical, up, diag_a))
            b = builder.select(horizontal, right, builder.select(vertical, down, diag_b))
            straight = builder.or_(horizontal, vertical)
            low_v = _splat_value(builder, args[9])
            high_v = _splat_value(builder, args[10])
            above_b = builder.or_(
                builder.fcmp_ordered(">", m, b), builder.and_(builder.fcmp_ordered("==", m, b), straight)
            )
            keep = builder.and_(
                builder.and_(builder.fcmp_ordered(">", m, low_v), builder.fcmp_ordered(">", m, a)), above_b
            )
            strong = builder.and_(keep, builder.fcmp_ordered(">", m, high_v))
            v8i8 = ir.VectorType(ir.IntType(8), LANES)
            label = builder.select(
                keep, builder.select(strong, ir.Constant(v8i8, [2] * LANES), ir.Constant(v8i8, [1] * LANES)),
                ir.Constant(v8i8, [0] * LANES),
            )  # fmt: skip
            v8i32 = ir.VectorType(ir.IntType(32), LANES)
            lanes = ir.Constant(v8i32, list(range(LANES)))
            first = builder.trunc(context.cast(builder, args[5], first_t, types.intp), ir.IntType(32))
            last = builder.trunc(context.cast(builder, args[6], last_t, types.intp), ir.IntType(32))
            undef = ir.Constant(v8i32, ir.Undefined)
            zeros = ir.Constant(v8i32, [0] * LANES)
            first_v = builder.shuffle_vector(
                builder.insert_element(undef, first, ir.Constant(ir.IntType(32), 0)), undef, zeros
            )
            last_v = builder.shuffle_vector(
                builder.insert_element(undef, last, ir.Constant(ir.IntType(32), 0)), undef, zeros
            )
            inside = builder.and_(builder.icmp_signed(">=", lanes, first_v), builder.icmp_signed("<=", lanes, last_v))
            zfirst = builder.trunc(context.cast(builder, args[7], zfirst_t, types.intp), ir.IntType(32))
            zlast = builder.trunc(context.cast(builder, args[8], zlast_t, types.intp), ir.IntType(32))
            zfirst_v = builder.shuffle_vector(
                builder.insert_element(undef, zfirst, ir.Constant(ir.IntType(32), 0)), undef, zeros
            )
            zlast_v = builder.shuffle_vector(
                builder.insert_element(undef, zlast, ir.Constant(ir.IntType(32), 0)), undef, zeros
            )
            cleared = builder.and_(
                builder.icmp_signed(">=", lanes, zfirst_v), builder.icmp_signed("<=", lanes, zlast_v)
            )
            edges_data = context.make_array(edges_t)(context, builder, args[11]).data
            edge_pointer = builder.bitcast(builder.gep(edges_data, [index]), v8i8.as_pointer())
            old = builder.load(edge_pointer, align=1)
            kept = builder.select(cleared, ir.Constant(v8i8, [0] * LANES), old)
            builder.store(builder.select(inside, label, kept), edge_pointer, align=1)
            bits = builder.bitcast(builder.and_(strong, inside), ir.IntType(LANES))
            return builder.zext(bits, i64)

        return types.int64(mag, gx, gy, k, width, first, last, zfirst, zlast, low, high, edges), codegen

    return nms8


nms8: Final = _nms8_intrinsic()
"""``nms8(mag, gx, gy, k, width, first, last, zfirst, zlast, low, high, edges) -> strong``: non-maximum
suppression (the sector rule and tie-breaking of `canny.nms_pixel`) of the flat planes at the 8 flat indices
``k .. k + 7`` of an image `width` wide, none on the image border; lanes ``first .. last`` (0-7) get their label
(EDGE_NONE, EDGE_WEAK, EDGE_STRONG) in `edges`, the other lanes of ``zfirst .. zlast`` get EDGE_NONE, the rest
keep theirs. Returns the bit mask of the labelled lanes that are EDGE_STRONG."""


def _push_lanes8_python(stack: Any, top: Any, k: Any, bits: Any) -> int:
    top = int(top)
    for lane in range(LANES):
        if (int(bits) >> lane) & 1:
            stack[top] = int(k) + lane
            top += 1
    return top


def _push_lanes8_intrinsic() -> Any:
    if numba.config.DISABLE_JIT:
        return _push_lanes8_python

    @intrinsic
    def push_lanes8(typingctx: Any, stack: Any, top: Any, k: Any, bits: Any) -> Any:
        is_stack = isinstance(stack, types.Array) and stack.ndim == 1 and stack.dtype == types.int32
        if not is_stack or not all(isinstance(x, types.Integer) for x in (top, k, bits)):
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            stack_t, top_t, k_t, bits_t = signature.args
            i32 = ir.IntType(32)
            v8i32 = ir.VectorType(i32, LANES)
            top_i = context.cast(builder, args[1], top_t, types.intp)
            k32 = builder.trunc(context.cast(builder, args[2], k_t, types.intp), i32)
            mask = builder.bitcast(
                builder.trunc(context.cast(builder, args[3], bits_t, types.intp), ir.IntType(LANES)),
                ir.VectorType(ir.IntType(1), LANES),
            )
            undef = ir.Constant(v8i32, ir.Undefined)
            splat = builder.shuffle_vector(
                builder.insert_element(undef, k32, ir.Constant(i32, 0)), undef, ir.Constant(v8i32, [0] * LANES)
            )
            indices = builder.add(splat, ir.Constant(v8i32, list(range(LANES))))
            data = context.make_array(stack_t)(context, builder, args[0]).data
            pointer = builder.gep(data, [top_i])
            compress = cgutils.get_or_insert_function(
                builder.module,
                ir.FunctionType(ir.VoidType(), [v8i32, pointer.type, mask.type]),
                "llvm.masked.compressstore.v8i32",
            )
            builder.call(compress, [indices, pointer, mask])
            popcount = cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(ir.IntType(LANES), [ir.IntType(LANES)]), "llvm.ctpop.i8"
            )
            count = builder.zext(builder.call(popcount, [builder.bitcast(mask, ir.IntType(LANES))]), ir.IntType(64))
            return builder.add(top_i, count)

        return types.int64(stack, top, k, bits), codegen

    return push_lanes8


push_lanes8: Final = _push_lanes8_intrinsic()
"""``push_lanes8(stack, top, k, bits) -> top``: append to ``stack[top:]`` the flat indices ``k + lane`` (int32) of
the lanes set in the 8-bit mask `bits`, in lane order (one compressing store); returns the new top."""
