"""ContourTracer: the rope's edge component, its closed outer contour (Freeman chain) and subpixel positions."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ropecam.device.pipeline import _kernels as K
from ropecam.device.pipeline._kernels.outline import draw_join, pick_open_ends
from ropecam.device.pipeline._views import as_ro, cell_property, f32, i32, ro
from ropecam.device.pipeline.workspace import ContourBuffers, expose

if TYPE_CHECKING:
    from ropecam.device.pipeline.edges import EdgeDetector

__all__ = ["BORDER_FIXED_END_PX", "ContourTracer"]

BORDER_FIXED_END_PX = 2.0
"""A fixed end nearer the image border than this (px) is not a rope's: its outline's border contacts all count."""

_NO_MASK = np.zeros((1, 1), np.uint8)
_NO_MASK.flags.writeable = False
"""The static-mask placeholder of `trace` (no mask: an out-and-back walk is kept as it is)."""


@expose("buffers", ContourBuffers)
class ContourTracer:
    """Keep the largest edge component, trace its outer boundary clockwise and refine it to subpixel positions.

    Parameters
    ----------
    height, width
        Image size.
    capacity
        Maximum number of contour points.
    min_pixels
        Smallest component accepted.
    """

    def __init__(
        self, height: int, width: int, capacity: int, min_pixels: int, buffers: ContourBuffers | None = None
    ) -> None:
        self.shape = (height, width)
        self.min_pixels = int(min_pixels)
        if buffers is None:
            buffers = ContourBuffers.make(height, width, capacity)
        elif buffers.labels.shape != self.shape or buffers.points.shape[0] != capacity:
            raise ValueError(f"buffers are for {buffers.labels.shape} images and {buffers.points.shape[0]} points")
        self.buffers = buffers
        """The labels, chain, points and counts (`ContourBuffers`; each also a read-only attribute: ``self.points``).
        ``counts`` holds, of the last trace: component pixels, ROI contacts, chain pixels on the image border, (after
        `detect_and_trace`) the edge pixels found and the contour's point count (`K.CONTOUR_POINTS`): the kernels
        write them (`steady_frame` the point count too), the attributes below read them on demand."""
        self._counts = buffers.counts
        self.count = 0
        self.contacts = -1
        self.on_border = -1
        self.joined = False
        """Whether the contour of the last `trace_next` was joined to the contour it dropped."""
        self.chain_ro = ro(self.chain)
        self.points_ro = ro(self.points)
        self._width32 = np.int32(width)
        self._height32 = np.int32(height)
        self._min32 = i32(self.min_pixels)
        self._detector: EdgeDetector | None = None
        self._detect_args: tuple[Any, ...] = ()
        """The arguments of `detect_and_trace` after the frame and the spans (the detector's buffers, then ours)."""

    # The counts (`ContourBuffers.counts`) as attributes, read and written on demand.
    component_px = cell_property("_counts", 0, "Pixels of the last traced component.")
    contacts = cell_property("_counts", 1, "ROI contacts of the last traced contour (-1: not counted, `roi_contacts`).")
    on_border = cell_property("_counts", 2, "Chain pixels on the image border of the last contour (-1: not counted).")
    count = cell_property("_counts", K.CONTOUR_POINTS, "Points of the last traced contour (0: none).")

    def trace(
        self,
        edges: NDArray[np.uint8],
        lo: NDArray[np.int32],
        hi: NDArray[np.int32],
        mag: NDArray[np.float32],
        gx: NDArray[np.float32],
        gy: NDArray[np.float32],
        edge_list: NDArray[np.int32] | None = None,
        n_edges: int = 0,
    ) -> int:
        """Trace the rope contour in `edges` (modified: other components are cleared) inside the spans.

        `edge_list` (optional): the first `n_edges` entries are the flat indices of every edge pixel inside the
        spans, in any order (as `EdgeDetector.detect` leaves them in its `stack`); the component is then
        chosen in time proportional to the edges instead of the span pixels, and `K.trace_rope` also takes noise
        spurs and small loops out of the outline (`prune_excursions`), which the path without it does not (only
        tests call that path). `edges` must then be 0 next to the spans outside them, as `EdgeDetector.detect`
        leaves it.

        Returns
        -------
        int
            The number of contour points (0 when no component has `min_pixels` pixels). `chain` (int32 row, col),
            `codes` (Freeman) and `points` (float32 subpixel row, col) hold them until the next call; with
            `edge_list`, `contacts` holds their ROI contacts (as `roi_contacts` with these spans) and `on_border`
            how many lie on the image border.
        """
        if edge_list is not None:
            # One kernel: component, trace, subpixel positions, ROI contacts and border pixels. The arrays go as
            # they are (an `as_ro` or a NumPy scalar costs 0.5-1.5 us here): read-only views, as the pipeline and
            # `EdgeDetector` keep them, match the kernel's signature; writable ones work, through the slow path.
            n = K.trace_rope(
                edges, lo, hi, edge_list, int(n_edges), self._min32, True, _NO_MASK, mag, gx, gy, self.group
            )
            self.count = n if n > 0 else 0  # FULL: a contour longer than the buffers is not a rope
            return self.count
        size = K.keep_largest_component(edges, as_ro(lo), as_ro(hi), self._min32, self.labels, self.stack, self.start)
        self.component_px = max(int(size), 0)
        self.contacts = -1
        self.on_border = -1
        if size < 0:
            self.count = 0
            return 0
        lo, hi = as_ro(lo), as_ro(hi)
        n = K.trace_contour(ro(edges), lo, hi, self.start[0], self.start[1], self.chain, self.codes)
        if n < 0:  # FULL: a contour longer than the buffers is not a rope
            self.count = 0
            return 0
        K.refine_subpixel(as_ro(mag), as_ro(gx), as_ro(gy), self.chain_ro, n, self.points)
        self.count = int(n)
        return self.count

    def detect_and_trace(
        self, detector: EdgeDetector, frame: NDArray[np.uint8], lo: NDArray[np.int32], hi: NDArray[np.int32]
    ) -> int:
        """Detect the edges of `frame` inside the spans (``detector.detect(frame, lo, hi)``) and trace the rope
        contour in them (`trace` with the detector's planes and edge list), in one kernel call (`detect_and_trace`):
        the same results in the detector (`edges`, `gx`, `gy`, `mag`, `smooth`, `count`, ...) and here.

        `frame` (uint8 of the detector's shape, read-only or writable), `lo` and `hi` (read-only int32) are passed
        as they are: C-contiguous arrays of these types take the kernel's fast path, others its slow type
        conversion (or a TypeError).

        Returns
        -------
        int
            The number of contour points, as `trace` (0: no component of `min_pixels` pixels, or a contour longer
            than the buffers).

        Raises
        ------
        ValueError
            A frame of another shape than the detector's, spans of another length.
        RuntimeError
            The edge kernel refused its arguments.
        """
        if frame.shape != detector.shape:
            raise ValueError(f"frame shape is {frame.shape}, expected {detector.shape}")
        args = self._detect_args if detector is self._detector else self.detect_args(detector)
        return self.adopt(detector, frame, lo, hi, K.detect_and_trace(frame, lo, hi, *args))

    def trace_next(self, detector: EdgeDetector, lo: NDArray[np.int32], hi: NDArray[np.int32]) -> int:
        """Drop the contour of the last `detect_and_trace` (with `detector`, in the spans `lo`/`hi`) from the
        detector's edges and trace the largest component left, as `detect_and_trace` traced (same static mask;
        the detector's edge list then lists the pixels kept). A cold path: the caller found that the traced
        component is not the rope (`RopeLocator`: not attached to a configured fixed end).

        Returns
        -------
        int
            The number of contour points, as `detect_and_trace` (0: no other component of `min_pixels` pixels);
            `joined` says whether the contour passes next to the dropped one's pixels.
        """
        lo, hi = as_ro(lo), as_ro(hi)
        listed = detector.stack[: detector.count]
        flat = detector.edges.reshape(-1)
        # The traced chain and its 8 neighbours go; what it joined (a rope whose tip lies across a plate's edge)
        # stays, its own component once the chain is gone.
        height, width = self.shape
        chain = self.chain[: self.count]
        gone = np.zeros((height + 2, width + 2), np.bool_)
        for dr in (0, 1, 2):
            for dc in (0, 1, 2):
                gone[chain[:, 0] + dr, chain[:, 1] + dc] = True
        others = listed[(flat[listed] != 0) & ~gone[1:-1, 1:-1].reshape(-1)[listed]].copy()
        flat[listed] = 0
        flat[others] = 1
        detector.stack[: len(others)] = others
        detector.count = len(others)
        n = K.trace_rope(
            detector.edges, lo, hi, ro(detector.stack), len(others), self._min32, False,
            detector.static_mask_ro, detector.mag_ro, detector.gx_ro, detector.gy_ro, self.group,
        )  # fmt: skip
        self.count = n if n > 0 else 0
        # Joined to what was dropped: the new contour passes next to the dropped chain's pixels.
        r, c = (self.chain[: self.count] + 1).T  # in `gone`'s padded frame
        self.joined = bool((gone[r - 1, c] | gone[r + 1, c] | gone[r, c - 1] | gone[r, c + 1]).any())
        return self.count

    def rejoin_gap(self, detector: EdgeDetector, reach_px: int) -> int:
        """Join the two line ends of the last traced component that lie within `reach_px` (per axis) of each other
        about half the chain apart (`K.pick_open_ends`): a gap in one side of the band, where noise or texture broke
        its edge (the outline is then a tree walked out and back, and the split's two sides differ in length). The
        component (1 in the detector's edges, in its spans) is copied, the join drawn on the copy (`K.draw_join`)
        and traced again; kept when the new chain walks at most `K.JOINED_REVISITS` of its pixels twice (a ring),
        spurs pruned and refined as `trace` does. A cold path (a frame that found no split): it allocates. Returns
        the new point count, written into `chain`, `codes`, `points` and `count`, or 0 (nothing written)."""
        n = self.count
        lo, hi = detector.spans
        if n < 8 or lo is None:
            return 0
        edges = (detector.edges == 1).astype(np.uint8)
        chain = self.chain[:n].copy()
        scratch = np.empty(n, np.int32)
        i, j = pick_open_ends(edges, chain, i32(n), np.int64(reach_px), scratch)
        if i < 0:
            return 0
        width = self.shape[1]
        a = np.int64(chain[i, 0]) * width + chain[i, 1]
        b = np.int64(chain[j, 0]) * width + chain[j, 1]
        changed, _ = draw_join(edges, as_ro(lo), as_ro(hi), a, b, np.int64(-1))
        if changed == 0:
            return 0
        first = int(np.flatnonzero(edges.reshape(-1))[0])
        capacity = self.chain.shape[0]
        new_chain = np.empty((capacity, 2), np.int32)
        codes = np.empty(capacity, np.int32)
        m = K.trace_contour(
            ro(edges), as_ro(lo), as_ro(hi), i32(first // width), i32(first % width), new_chain, codes
        )  # fmt: skip
        if m <= 0 or K.count_revisits(ro(new_chain), i32(m), edges) > K.JOINED_REVISITS * m:
            return 0
        m = K.prune_excursions(new_chain, codes, i32(m), np.int64(width), np.empty(edges.size, np.int32))
        points = np.empty((capacity, 2), np.float32)
        K.refine_subpixel(detector.mag_ro, detector.gx_ro, detector.gy_ro, ro(new_chain), i32(m), points)
        self.chain[:m] = new_chain[:m]
        self.codes[:m] = codes[:m]
        self.points[:m] = points[:m]
        self.count = int(m)
        return self.count

    def forget_args(self) -> None:
        """Make `detect_args` again on the next call (the detector's thresholds changed)."""
        self._detector = None

    def detect_args(self, detector: EdgeDetector) -> tuple[Any, ...]:
        """The arguments of the `detect_and_trace` kernel after the frame and the spans, for `detector`: its
        weights and thresholds, our smallest component, its groups of buffers (`Static`, `EdgeWork`, `Planes`),
        then ours (`Contour`); made once per detector."""
        if detector is not self._detector:
            d = detector
            self._detect_args = (d.weights_ro, d.low, d.high, self._min32, d.static, d.work, d.planes, self.group)
            self._detector = detector
        return self._detect_args

    def adopt(
        self, detector: EdgeDetector, frame: NDArray[np.uint8], lo: NDArray[np.int32], hi: NDArray[np.int32], n: int
    ) -> int:
        """Take the results of a `detect_and_trace` kernel call (made here) of `frame` in the spans `lo`/`hi`, which
        returned `n`, into this tracer and `detector`, as `detect_and_trace` does; returns the number of contour
        points (0 when none). Raises RuntimeError as `detect_and_trace`."""
        self.count = n if n > 0 else 0  # FULL: a contour longer than the buffers is not a rope
        self.adopt_steady(detector, frame, lo, hi)
        if detector.count < 0:
            raise RuntimeError(f"detect_edges returned status {detector.count} (frame {frame.shape}, spans {lo.shape})")
        return self.count

    def adopt_steady(
        self, detector: EdgeDetector, frame: NDArray[np.uint8], lo: NDArray[np.int32], hi: NDArray[np.int32]
    ) -> None:
        """Take the results of the `detect_and_trace` call `steady_frame` made of `frame` in the spans `lo`/`hi` (the
        counts it wrote, the point count too, are read on demand; it refused a bad edge stage before the call)."""
        detector.counts = self._counts  # its edge pixel count is ours (`EdgeDetector.count`)
        detector.spans = (lo, hi)
        detector.frame = frame

    def roi_contacts(self, lo: NDArray[np.int32], hi: NDArray[np.int32]) -> int:
        """Return how many contour pixels touch the border of the region of interest `lo`/`hi` (the `contacts`
        counted by `trace` are the same for the spans it got)."""
        return int(K.count_roi_contacts(self.chain_ro, np.int32(self.count), as_ro(lo), as_ro(hi), self._width32))

    def border_contacts(self, fixed_rc: tuple[float, float] | None, exclude_px: float) -> int:
        """Return how many contour pixels lie on the image border farther than `exclude_px` from the fixed end.

        A fixed end on the image border (within `BORDER_FIXED_END_PX`) excludes none: a rope is fixed inside the
        view (docs/pipeline.md, "Known limits"), and an outline whose fixed end was found on the border runs out
        of the frame along something else (a clamp's rod, a static cable), which is not the rope's end."""
        if self.on_border == 0 or self.count == 0:
            return 0
        height, width = self.shape
        if fixed_rc is None or min(fixed_rc[0], fixed_rc[1], height - 1 - fixed_rc[0], width - 1 - fixed_rc[1]) < (
            BORDER_FIXED_END_PX
        ):
            fr, fc = np.float32(-1e9), np.float32(-1e9)
        else:
            fr, fc = f32(fixed_rc[0]), f32(fixed_rc[1])
        return int(
            K.count_border_contacts(
                self.chain_ro, np.int32(self.count), self._height32, self._width32, fr, fc, f32(exclude_px)
            )
        )
