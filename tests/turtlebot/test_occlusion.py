"""Analyse's occlusion model: probability per ray, clustering into windows on the circle."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st
from tb4.occlusion import Window, cluster, detect, occlusion_probability
from tb4.spin import mask_of

from .strategies import windows


@given(windows())
def test_clustering_recovers_separated_windows(case):
    rays, expected = case
    assert cluster(mask_of(expected, rays)) == expected


@given(st.lists(st.booleans(), min_size=1, max_size=200), st.integers(1, 6))
def test_clusters_are_the_maximal_runs_of_occluded_rays(mask, min_length):
    n = len(mask)
    found = cluster(mask, min_length)
    covered = [0] * n
    for w in found:
        assert 1 <= w.length <= n and w.length >= min_length
        for i in w.rays(n):
            assert mask[i]
            covered[i] += 1
        if w.length < n:  # maximal: clear rays on both sides
            assert not mask[(w.start - 1) % n]
            assert not mask[(w.start + w.length) % n]
    assert all(c <= 1 for c in covered)
    # every occluded ray not in a window belongs to a run shorter than min_length
    for i in range(n):
        if mask[i] and not covered[i]:
            run = 1
            j = (i + 1) % n
            while mask[j] and j != i and run < n:
                run, j = run + 1, (j + 1) % n
            j = (i - 1) % n
            while mask[j] and j != i and run < n:
                run, j = run + 1, (j - 1) % n
            assert run < min_length
    assert [w.start for w in found] == sorted(w.start for w in found)


def test_a_fully_occluded_scanner_is_one_window():
    assert cluster([True] * 10) == [Window(0, 10)]
    assert cluster([False] * 10) == []


def test_a_window_across_ray_zero_is_one_window():
    mask = [True, True, False, False, False, True]
    assert cluster(mask) == [Window(5, 3)]
    assert Window(5, 3).degrees(6) == (0.0, 180.0)  # rays at 300, 0 and 60 deg


def test_probability_is_the_fraction_of_invalid_readings():
    scans = [[1.0, None, 0.01, 2.0], [1.0, None, 3.0, None]]
    assert occlusion_probability(scans) == [0.0, 1.0, 0.5, 0.5]


@settings(max_examples=60, deadline=None)
@given(windows(rays=90, min_gap=1, min_length=3), st.integers(0, 2**32 - 1))
def test_detection_finds_the_debris_despite_dropouts(case, seed):
    """Debris rays are always empty; any other ray drops out in at most 2 of 10 scans, which
    stays under the 0.7 threshold: exactly the debris windows are found."""
    rays, expected = case
    rng = random.Random(seed)
    mask = mask_of(expected, rays)
    scans = [
        [None if mask[i] else round(rng.uniform(0.2, 11.0), 3) for i in range(rays)]
        for _ in range(10)
    ]
    for i in range(rays):
        for k in rng.sample(range(10), rng.randint(0, 2)):
            scans[k][i] = None
    assert detect(scans, threshold=0.7, min_length=3) == expected
