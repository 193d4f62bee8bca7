"""Archive container: round trip, atomic save, and clear errors on bad files."""
import json
import os

import numpy as np
import pytest

from sela_ros.core.storage import default_archive_path
from sela_ros.core.storage.archive import (
    REQUIRED_METADATA_KEYS,
    Archive,
    ArchiveError,
    check_settings,
    load_archive,
    make_metadata,
)

SETTINGS = {'dt': 1 / 240, 'gait_duration': 3.0, 'controller_version': 'cully2015-v1',
            'model_version': 'sela-hexapod-v1'}


def _archive(m=50, seed=0):
    rng = np.random.default_rng(seed)
    metadata = make_metadata(**SETTINGS, descriptor_name='final_xy',
                             descriptor_bounds=[[-1, 1], [-0.5, 0.5]], fitness_name='arc',
                             grid_shape=[8, 8], n_evaluations=1000, seed=seed)
    return Archive(params=rng.random((m, 36)), descriptors=rng.uniform(-1, 1, (m, 2)),
                   generic_reward=0.2 * rng.normal(size=(m, 3)), fitness=-rng.random(m),
                   metadata=metadata)


def _write_npz(path, **arrays):
    np.savez_compressed(path, **arrays)
    return path


def _arrays(archive):
    return {'params': archive.params, 'descriptors': archive.descriptors,
            'generic_reward': archive.generic_reward, 'fitness': archive.fitness,
            'metadata': np.array(json.dumps(archive.metadata))}


def test_round_trip(tmp_path):
    archive = _archive()
    path = archive.save(tmp_path / 'sub' / 'a.npz')
    loaded = load_archive(path, expected_settings=SETTINGS)
    for key in ('params', 'descriptors', 'generic_reward', 'fitness'):
        np.testing.assert_array_equal(getattr(loaded, key), getattr(archive, key))
    assert loaded.metadata == archive.metadata
    assert set(REQUIRED_METADATA_KEYS) <= set(loaded.metadata)
    assert len(loaded) == 50
    assert [p.name for p in path.parent.iterdir()] == ['a.npz']  # no temp file left


def test_normalised_descriptors_use_metadata_bounds():
    archive = _archive()
    archive.descriptors[0] = [-1.0, 0.5]
    archive.descriptors[1] = [5.0, -9.0]  # outside: clipped to the edge
    norm = archive.normalised_descriptors()
    assert norm.shape == (50, 2)
    np.testing.assert_allclose(norm[0], [0.0, 1.0])
    np.testing.assert_allclose(norm[1], [1.0, 0.0])
    assert norm.min() >= 0 and norm.max() <= 1


def test_save_overwrites_atomically(tmp_path):
    path = tmp_path / 'a.npz'
    _archive(m=10).save(path)
    _archive(m=20, seed=1).save(path)
    assert len(load_archive(path)) == 20


def test_missing_file(tmp_path):
    with pytest.raises(ArchiveError, match='no archive file.*sela-build-archive'):
        load_archive(tmp_path / 'nope.npz')


@pytest.mark.parametrize('name', ['a' * 300, 'x' * 5000 + '/y.npz', 'nul\0byte.npz'])
def test_unusable_path_is_an_archive_error(tmp_path, name):
    with pytest.raises(ArchiveError, match='cannot be used|no archive file'):
        load_archive(tmp_path / name)


@pytest.mark.parametrize('keep', [0.3, 0.6, 0.95])
def test_truncated_file(tmp_path, keep):
    path = _archive(m=500).save(tmp_path / 'a.npz')
    data = path.read_bytes()
    path.write_bytes(data[:int(len(data) * keep)])
    with pytest.raises(ArchiveError, match='truncated or corrupt.*sela-build-archive'):
        load_archive(path)


def test_corrupt_bytes(tmp_path):
    path = _archive(m=500).save(tmp_path / 'a.npz')
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 64] = os.urandom(64)
    path.write_bytes(bytes(data))
    with pytest.raises(ArchiveError, match='sela-build-archive'):
        load_archive(path)


def test_not_an_npz(tmp_path):
    path = tmp_path / 'a.npz'
    for content in (b'hello', b'', b'\x93NUMPY\x01\x00'):  # text, empty, a bare .npy
        path.write_bytes(content)
        with pytest.raises(ArchiveError, match='is not an .npz file: it does not start as a '
                           'zip does.*sela-build-archive'):
            load_archive(path)


def test_missing_key(tmp_path):
    arrays = _arrays(_archive())
    del arrays['generic_reward']
    path = _write_npz(tmp_path / 'a.npz', **arrays)
    with pytest.raises(ArchiveError, match=r"lacks key\(s\) \['generic_reward'\]"):
        load_archive(path)


def test_wrong_shape(tmp_path):
    arrays = _arrays(_archive())
    arrays['params'] = arrays['params'][:, 0]
    path = _write_npz(tmp_path / 'a.npz', **arrays)
    with pytest.raises(ArchiveError, match=r'params must have shape \(M, n\) .*got \(50,\)'):
        load_archive(path)


def test_another_robot_s_number_of_parameters_is_its_own(tmp_path):
    arrays = _arrays(_archive())
    arrays['params'] = arrays['params'][:, :12]
    archive = load_archive(_write_npz(tmp_path / 'a.npz', **arrays))
    assert archive.params.shape == (50, 12)


def test_wrong_dtype(tmp_path):
    arrays = _arrays(_archive())
    arrays['fitness'] = np.arange(50)
    path = _write_npz(tmp_path / 'a.npz', **arrays)
    with pytest.raises(ArchiveError, match='fitness has dtype int64, expected a float'):
        load_archive(path)


def test_nan(tmp_path):
    arrays = _arrays(_archive())
    arrays['generic_reward'][3, 1] = np.nan
    path = _write_npz(tmp_path / 'a.npz', **arrays)
    with pytest.raises(ArchiveError, match='generic_reward holds 1 NaN'):
        load_archive(path)


def test_bad_metadata(tmp_path):
    arrays = _arrays(_archive())
    arrays['metadata'] = np.array('{not json')
    with pytest.raises(ArchiveError, match='metadata is not valid JSON'):
        load_archive(_write_npz(tmp_path / 'a.npz', **arrays))
    metadata = dict(_archive().metadata)
    del metadata['dt']
    arrays['metadata'] = np.array(json.dumps(metadata))
    with pytest.raises(ArchiveError, match=r"metadata lacks key\(s\) \['dt'\]"):
        load_archive(_write_npz(tmp_path / 'b.npz', **arrays))


def test_format_version(tmp_path):
    archive = _archive()
    archive.metadata['format_version'] = 99
    path = archive.save(tmp_path / 'a.npz')
    with pytest.raises(ArchiveError, match='format version 99'):
        load_archive(path)


@pytest.mark.parametrize('key, value', [('dt', 1 / 1000), ('gait_duration', 2.0),
                                        ('controller_version', 'other'),
                                        ('model_version', 'v0')])
def test_settings_mismatch(tmp_path, key, value):
    path = _archive().save(tmp_path / 'a.npz')
    expected = dict(SETTINGS, **{key: value})
    with pytest.raises(ArchiveError) as info:
        load_archive(path, expected_settings=expected)
    message = str(info.value)
    assert key in message and repr(value) in message and repr(SETTINGS[key]) in message
    assert 'sela-build-archive' in message


def test_settings_match_ignores_extra_keys_and_float_noise():
    check_settings(dict(SETTINGS), dict(SETTINGS, dt=1 / 240 + 1e-15,
                                        something_else=1))


def test_constructor_validates():
    archive = _archive()
    with pytest.raises(ArchiveError, match='generic_reward must have shape'):
        Archive(archive.params, archive.descriptors, archive.generic_reward[:, :2],
                archive.fitness, archive.metadata)
    with pytest.raises(ArchiveError, match=r'params must lie in \[0, 1\]'):
        Archive(archive.params + 1, archive.descriptors, archive.generic_reward,
                archive.fitness, archive.metadata)
    bad = dict(archive.metadata, descriptor_bounds=[[1, 0], [0, 1]])
    with pytest.raises(ArchiveError, match='low < high'):
        Archive(archive.params, archive.descriptors, archive.generic_reward,
                archive.fitness, bad)


def test_default_archive_path_is_in_package():
    path = default_archive_path()
    assert path.name == 'hexapod_archive.npz'
    assert path.parent.name == 'data' and path.parent.parent.name == 'sela_ros'


@pytest.mark.parametrize('name', ['8d', '2d'])
def test_shipped_archive_is_valid(name):
    from sela_ros.core.storage import shipped_archive_path

    path = shipped_archive_path(name)
    assert path.exists(), f'the shipped archive {path} is missing'
    archive = load_archive(path)
    assert path.stat().st_size <= 20 * 1024 * 1024
    assert len(archive) >= 2000
    dx, dy, dyaw = archive.generic_reward.T
    # forward, backward, sideways and turning gaits are all there
    assert np.any(dx > 0.1) and np.any(dx < -0.1)
    assert np.any(np.abs(dy) > 0.1) and np.any(np.abs(dyaw) > 0.5)
    try:
        from sim_bridge.settings import simulator_settings
    except ImportError:  # the archive's own checks above still ran
        return
    stamp = archive.simulator_settings
    load_archive(path, expected_settings=simulator_settings(
        stamp['dt'], stamp['gait_duration'], stamp['solver_iterations']))


def test_kernel_length_is_the_maps_own_and_sela_takes_it_unless_told_otherwise():
    from sela_ros.core.mission import make_sela

    flat = _archive()
    assert flat.kernel_sigma == 0.1  # the paper's, for a 2-D map
    rng = np.random.default_rng(1)
    meta = dict(flat.metadata, descriptor_bounds=[[-1, 1], [-1, 1]] + [[0, 1]] * 6)
    eight = Archive(params=flat.params, descriptors=rng.random((len(flat), 8)),
                    generic_reward=flat.generic_reward, fitness=flat.fitness, metadata=meta)
    assert eight.kernel_sigma == 0.3
    said = Archive(params=flat.params, descriptors=eight.descriptors,
                   generic_reward=flat.generic_reward, fitness=flat.fitness,
                   metadata=dict(meta, gp_kernel_sigma=0.25))
    assert said.kernel_sigma == 0.25
    for bad in (0, -1, 'x', float('nan'), True):  # unusable metadata: the default for 8-D
        assert Archive(params=flat.params, descriptors=eight.descriptors,
                       generic_reward=flat.generic_reward, fitness=flat.fitness,
                       metadata=dict(meta, gp_kernel_sigma=bad)).kernel_sigma == 0.3
    # The node's default (auto), or no value, is the archive's; a value given is kept.
    assert make_sela(eight, {'gp.kernel.sigma': 'auto'}).config.gp_kernel_sigma == 0.3
    assert make_sela(flat, {}).config.gp_kernel_sigma == 0.1
    assert make_sela(eight, {'gp.kernel.sigma': 0.2}).config.gp_kernel_sigma == 0.2


def test_an_8d_map_gives_the_fall_model_its_support_and_its_own_fall_kernel():
    from sela_ros.core.mission import make_sela

    flat = _archive()
    assert flat.stability is None and flat.fall_kernel_sigma == 0.1
    rng = np.random.default_rng(2)
    meta = dict(flat.metadata, descriptor_bounds=[[-1, 1], [-1, 1]] + [[0, 1]] * 6,
                descriptor_name='final_xy_duty_factors')
    eight = Archive(params=flat.params, descriptors=rng.random((len(flat), 8)),
                    generic_reward=flat.generic_reward, fitness=flat.fitness, metadata=meta)
    # Support: the sum of the six duty factors (the mean number of feet on the ground).
    np.testing.assert_allclose(eight.stability, eight.descriptors[:, 2:].sum(axis=1))
    assert eight.fall_kernel_sigma == 0.12
    other = Archive(params=flat.params, descriptors=eight.descriptors,
                    generic_reward=flat.generic_reward, fitness=flat.fitness,
                    metadata=dict(meta, descriptor_name='something_else', fall_kernel_sigma=0.2))
    assert other.stability is None and other.fall_kernel_sigma == 0.2
    sela = make_sela(eight, {'fall.kernel.sigma': 'auto'})
    assert sela.config.fall_kernel_sigma == 0.12
    assert sela.fall_risk.support_model is not None
    assert make_sela(flat, {}).fall_risk.support_model is None


def test_shipped_archives_by_name():
    from sela_ros.core.storage.archive import (
        SHIPPED_ARCHIVES,
        resolve_archive_path,
        shipped_archive_path,
    )

    assert resolve_archive_path('') == str(default_archive_path())
    assert resolve_archive_path('8d') == str(default_archive_path())
    two = load_archive(resolve_archive_path('2d'))
    eight = load_archive(resolve_archive_path(' 8d '))
    assert two.descriptors.shape[1] == 2 and eight.descriptors.shape[1] == 8
    assert len(eight) >= 10_000 and eight.metadata['archive_kind'] == 'cvt'
    assert eight.stability is not None and two.stability is None
    assert resolve_archive_path('/some/map.npz') == '/some/map.npz'
    assert set(SHIPPED_ARCHIVES) == {'8d', '2d', 'a1'}
    a1 = load_archive(resolve_archive_path('a1'))
    assert a1.metadata['robot'] == 'a1' and a1.descriptors.shape[1] == 6
    with pytest.raises(ArchiveError, match='shipped'):
        shipped_archive_path('3d')
