"""Shared helpers of the flocking tests."""

import numpy as np

from robofleet.flocking.model import LocalFrames, look


def world_decisions(algorithm, pattern, leader, followers, frames, rng=None):
    """Each follower's decision path in world coordinates (list of (K, 2) arrays) and slots."""
    paths, slots = [], []
    for i in range(len(followers)):
        d = algorithm.decide(look(frames, i, leader, followers), pattern, rng)
        paths.append(frames.to_world(i, d.path, followers[i]))
        slots.append(d.slot)
    return paths, slots


def single_frame(angle, hand):
    return LocalFrames(np.array([float(angle)]), np.array([float(hand)]))
