"""Compile (or load from numba's on-disk cache) the tracker's kernels."""

from __future__ import annotations

import numpy as np

from engine.physics.recursive import kernel_arguments


def warm_up() -> None:
    """Run every compiled kernel of the tracker once on tiny inputs.

    Call once at start-up in latency-sensitive programs so that the first
    tracked frame does not pay the compilation.
    """
    from engine.geometry import _kernels as geometry
    from engine.tracking import _cut_kernels as cut
    from engine.tracking import _histogram_kernels as histogram
    from engine.tracking import _image_kernels as image
    from engine.tracking import _lighting_kernel as light
    from engine.tracking import _occluder_kernels as occluder
    from engine.tracking._label_kernels import colour_spread, label_shares
    from engine.tracking._mean_kernels import masked_means, masked_values, mean
    from engine.tracking._noise_kernel import median_response
    from engine.tracking._refine_kernel import refine_chain
    from engine.tracking._shape_kernels import best_overlap

    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    geometry.polyline_crosses(square, True)
    geometry.outward_normals(square)
    geometry.perimeter(square)
    geometry.nearest(square, square)
    geometry.resample_polyline(square, 4, True)
    geometry.least_squares_similarity(square, square, np.ones(len(square), dtype=np.bool_))
    geometry.extent(square)
    median_response(np.zeros((3, 3), np.uint8), 6)
    some = np.ones((2, 2), np.bool_)
    for view in (np.ones((2, 2), np.float32), np.ones((3, 3), np.float32)[1:, 1:]):
        masked_means(view, some, some)  # the contour's box: the whole maps, or a view
        masked_values(view, some, some)
    mean(np.ones(200, np.float32))
    label_shares(np.zeros((2, 2), np.int32), np.ones((2, 2), np.uint8), 1)
    colour_spread(np.zeros((2, 2, 3), np.uint8), 1, 2)
    geometry.fixed_point(square, 16, 1e6)
    table = np.zeros(4096, np.float32)
    for picture in (np.zeros((2, 2, 3), np.uint8), np.zeros((2, 2, 1), np.uint8)):
        image.colour_bins(picture, 5, 4)
        image.colour_lookup(picture, 5, 4, table)
        flags = np.ones((2, 2), np.uint8)
        above, below = np.float32(0.5), np.float32(0.5)
        for lut in (table, np.empty(0, np.float32)):
            image.taught_counts(picture, 5, 4, flags, flags, flags, lut, above, below, 4096)
        centres = np.zeros((1, 2), np.int64)
        fg, bg = cut.learn_windows(picture, 5, 3, flags, flags, centres, 1, 512)
        half = np.full((2, 2), 0.5, np.float32)
        cut.local_probability(picture, 5, 3, flags, centres, 1, fg, bg, 12.0, 1.0, half)
        cut.settle(*cut.band_graph(half, 1.0, picture, half, np.ones(4))[1:])
        colours = light.grid_sample(picture, 8)
        light.interior(flags, 0, (0, 0), 1, picture)
        light.carried(np.zeros((1, 2), np.int64), colours, np.zeros((2, 3)), picture)
        light.ratio_step(colours, colours, light.LOG, 8, 247, 102)
        labels = np.zeros((2, 2), np.int32)
        occluder.ring_histogram(picture, (0, 0), 1, flags, flags, flags, 3)
        occluder.label_histograms(picture, (0, 0), labels, 1, 1, 3)
    bins = np.ones(8)
    histogram.odds_table(bins, bins, 1e-3)
    histogram.blended(bins, bins, 0.05)
    histogram.shares(np.ones(8, np.int64))
    grid = np.ones((2, 2), np.bool_)
    judged = grid.copy()
    judged.setflags(write=False)  # the evidence's silhouette is read-only
    for shape in (grid, judged):
        best_overlap(grid[None], np.ones(1, np.bool_), shape)
    maps = np.zeros((4, 4), np.float32)
    image.scale_and_clip(image.sobel_magnitude(maps), 1.0)
    image.scale_odds(maps, maps)
    image.contrast_odds(maps, maps, 12.0, 2.0)
    image.side_contrast(maps, 0.0, 0.0, square, 2)
    image.occluded(
        maps, np.zeros((4, 4), np.uint8), np.zeros((4, 4), np.uint8), np.zeros((2, 3)), 0.35, 166
    )
    image.boundary_search(
        maps, maps, 1, square, square, 1, 1.0, 0.5, 0.1, np.empty(4), np.empty(4), np.zeros(4)
    )
    image.contour_pull(maps, maps, 1, square, 1, 1.0, 0.5, 0.1, np.empty((4, 2)), np.zeros(4))
    refine_chain(
        maps,
        maps,
        2,
        np.zeros(2),
        square,
        np.ones(2, np.int64),
        np.ones(3),
        0.1,
        np.asarray(kernel_arguments(1.0, 4, True), np.float64),
        np.empty((4, 2)),
        np.zeros(4),
    )
