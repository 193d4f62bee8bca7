"""A synthetic archive for tests that run experiments without a real map."""
import numpy as np

from sela_ros.core.storage import Archive, make_metadata
from sim_bridge.settings import simulator_settings


def tiny_archive(path, n=8, seed=0):
    """A synthetic archive: random gaits with made-up intact outcomes (fast to run)."""
    rng = np.random.default_rng(seed)
    gr = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(-0.5, 0.5, n)])
    metadata = make_metadata(**simulator_settings(), descriptor_name='final_xy',
                             descriptor_bounds=[[-0.6, 0.6], [-0.6, 0.6]],
                             fitness_name='none', grid_shape=[4, 4], n_evaluations=n,
                             seed=seed)
    Archive(rng.random((n, 36)), gr[:, :2], gr, np.zeros(n), metadata).save(path)
    return path
