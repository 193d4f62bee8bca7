"""Map files: map_server's YAML + PGM/PNG, the project's YAML, and their errors."""
import numpy as np
import pytest

from sela_ros.core.planning.maps import (
    MapError,
    grid_from_description,
    load_map_file,
    occupancy_from_image,
    read_pgm,
)

# Image rows top (far, +y) to bottom: 0 black = occupied, 255 white = free, 205 unknown grey.
PIXELS = np.array([[0, 0, 0, 0],
                   [255, 205, 255, 0],
                   [255, 255, 255, 255]], dtype=np.uint8)


def write_pgm(path, pixels, binary=True, comment=True):
    h, w = pixels.shape
    header = f'P{5 if binary else 2}\n' + ('# CREATOR: test\n' if comment else '') + \
        f'{w} {h}\n255\n'
    with open(path, 'wb') as handle:
        handle.write(header.encode())
        if binary:
            handle.write(pixels.tobytes())
        else:
            handle.write(' '.join(str(v) for v in pixels.reshape(-1)).encode())


def write_map_yaml(path, image, negate=0):
    path.write_text(f'image: {image}\nresolution: 0.5\norigin: [-1.0, 2.0, 0.0]\n'
                    f'negate: {negate}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n')
    return path


@pytest.mark.parametrize('binary', [True, False])
def test_pgm_is_read_with_the_top_row_first(tmp_path, binary):
    write_pgm(tmp_path / 'm.pgm', PIXELS, binary=binary)
    np.testing.assert_allclose(read_pgm(tmp_path / 'm.pgm'), PIXELS / 255.0)


def test_map_server_yaml_and_pgm(tmp_path):
    write_pgm(tmp_path / 'm.pgm', PIXELS)
    grid = load_map_file(write_map_yaml(tmp_path / 'm.yaml', 'm.pgm'))
    assert grid.resolution == 0.5 and tuple(grid.origin) == (-1.0, 2.0)
    # Grid row 0 is the image's bottom row (all free); the top row (all black) is occupied.
    assert grid.occupied.tolist() == [[False] * 4, [False, True, False, True], [True] * 4]
    assert grid.world_to_cell((-0.9, 2.1)) == (0, 0) and grid.is_free((0, 0))
    free_unknown = load_map_file(tmp_path / 'm.yaml', unknown_is_occupied=False)
    assert not free_unknown.occupied[1, 1] and free_unknown.occupied[1, 3]


def test_negate_and_png_read_like_pgm(tmp_path):
    from PIL import Image

    Image.fromarray(255 - PIXELS).save(tmp_path / 'neg.png')
    grid = load_map_file(write_map_yaml(tmp_path / 'neg.yaml', 'neg.png', negate=1))
    write_pgm(tmp_path / 'm.pgm', PIXELS)
    assert grid.occupied.tolist() == \
        load_map_file(write_map_yaml(tmp_path / 'm.yaml', 'm.pgm')).occupied.tolist()
    # An RGB png reads as the mean of its channels.
    Image.fromarray(np.stack([PIXELS] * 3, axis=-1)).save(tmp_path / 'rgb.png')
    rgb = load_map_file(write_map_yaml(tmp_path / 'rgb.yaml', 'rgb.png'))
    assert rgb.occupied.tolist() == grid.occupied.tolist()


def test_scale_and_raw_modes():
    shade = np.array([[0.0, 0.45, 1.0]])
    scale = occupancy_from_image(shade, mode='scale', occupied_thresh=0.65, free_thresh=0.25)
    assert scale.tolist() == [[100, 75, 0]]  # occupancy 0.55: (0.55 - 0.25) / 0.4 * 100
    raw = occupancy_from_image(np.array([[0, 50 / 255, 100 / 255, 200 / 255]]), mode='raw')
    assert raw.tolist() == [[0, 50, 100, -1]]


def test_project_yaml_still_loads(tmp_path):
    path = tmp_path / 'p.yaml'
    path.write_text('resolution: 0.1\norigin: [-1, -1]\nwidth: 2\nheight: 2\n'
                    'obstacles: [0, 0, 0.5, 0.5]\n')
    assert load_map_file(path).occupied.sum() > 0


@pytest.mark.parametrize('text, match', [
    ('resolution: 0.1\norigin: 5\nwidth: 2\nheight: 2\n', r'map.origin must be a list'),
    ('resolution: 0.1\norigin: [0, 0]\nwidth: 2\nheight: 2\nobstacles: null\n',
     r'map.obstacles must be a flat list'),
    ('resolution: 0.1\norigin: [0, 0]\nwidth: 2\nheight: 2\nobstacles: [0, 0, a, 1]\n',
     r'map.obstacles\[2\] must be a finite number'),
    ('resolution: yes\norigin: [0, 0]\nwidth: 2\nheight: 2\n', r'map.resolution'),
    ('image: absent.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n', r'absent.pgm does not exist'),
    ('image: 5\nresolution: 0.1\norigin: [0, 0, 0]\n', r'image must be a file name'),
    ('image: m.pgm\nresolution: 0.1\norigin: 5\n', r'origin must be a list'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0.5]\n', r'yaw 0.5 is not supported'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: fancy\n', r'mode must be'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.9\n', r'free_thresh'),
    ('image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: maybe\n', r'negate'),
    ('image: m.pgm\norigin: [0, 0, 0]\n', r'need resolution and origin'),
    ('image: bad.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n', r'not a PGM'),
    ('image: short.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n', r'truncated'),
    ('- a list\n', r'expected a mapping'),
])
def test_wrong_fields_are_clear_errors(tmp_path, text, match):
    write_pgm(tmp_path / 'm.pgm', PIXELS)
    (tmp_path / 'bad.pgm').write_bytes(b'GIF89a')
    (tmp_path / 'short.pgm').write_bytes(b'P5 4 3 255\n\x00\x00')
    path = tmp_path / 'map.yaml'
    path.write_text(text)
    with pytest.raises(MapError, match=match) as info:
        load_map_file(path)
    assert str(path) in str(info.value)


def test_map_description_types():
    with pytest.raises(MapError, match='map.origin'):
        grid_from_description(0.1, None, 1, 1, [])
    with pytest.raises(MapError, match='map.width'):
        grid_from_description(0.1, [0, 0], 'wide', 1, [])
    assert grid_from_description(0.1, (0, 0), 1, 1, np.array([0.2, 0.2, 0.4, 0.4])) \
        .occupied.any()


def test_a_map_of_more_cells_than_the_planner_holds_is_refused_with_the_reason():
    from sela_ros.core.planning.maps import MAX_CELLS, check_geometry

    check_geometry(0.05, (-175.0, -175.0), 350.0, 350.0)  # 49 M cells: taken
    with pytest.raises(MapError, match=r'400 M cells, more than the planner holds \(50 M'):
        check_geometry(0.05, (0.0, 0.0), 1000.0, 1000.0)
    with pytest.raises(MapError, match='a coarser resolution or a smaller map'):
        grid_from_description(0.001, [0.0, 0.0], 10.0, 10.0, [])
    assert MAX_CELLS == 50_000_000
