"""Occupancy maps as users have them: map_server's YAML + image, or the project's own YAML.

Two file formats are read into an :class:`~sela_ros.core.planning.OccupancyGrid`:

* **map_server** (what ``nav2_map_server``/``map_saver`` write, and what RViz users load): a
  YAML file with ``image`` (PGM or PNG, relative to the YAML file), ``resolution``,
  ``origin: [x, y, yaw]``, ``negate``, ``occupied_thresh``, ``free_thresh`` and ``mode``
  (``trinary``, the default; ``scale``; ``raw``). Pixels are read as map_server reads them:
  the shade (mean of the colour channels, 0 black .. 1 white) gives the occupancy
  probability ``1 - shade`` (``shade`` if ``negate``), then the thresholds give occupied
  (100), free (0) or unknown (-1). The image's top row is the map's far (+y) edge.
* **the project's own** (``config/obstacle_map.yaml``): ``resolution``, ``origin: [x, y]``,
  ``width``, ``height`` (metres) and ``obstacles``, a flat list of rectangles
  ``[xmin, ymin, xmax, ymax, ...]``.

Unknown cells (-1) are occupied unless the caller says otherwise (``unknown_is_occupied``):
a robot that learns on-line should not plan through space nobody has seen.

Every wrong field is a :class:`MapError` (a ``ValueError``) that names the file and the
field and says what was expected, so that a node can report it and keep its current map.
"""
from __future__ import annotations

import math
import numbers
import os

import numpy as np

from sela_ros.core.planning.grid import OccupancyGrid

MAP_SERVER_MODES = ('trinary', 'scale', 'raw')

#: The planner's map when none is given (the ``planner`` node's ``map.*`` defaults, and the
#: experiments' without ``--map``): an empty 8 m square centred on the start, which holds every
#: goal the README and docs use. Goals off it are refused by the nodes and the experiments.
DEFAULT_MAP = {'resolution': 0.05, 'origin': (-4.0, -4.0), 'width': 8.0, 'height': 8.0}
#: What a map may be, wherever it comes from (the ``map.*`` parameters, a map file, a map on
#: a topic): a cell of 1 mm to 1 m (m), a side of 1 cm to 1 km (m), a corner within 100 km
#: of the odom origin (m), at most :data:`MAX_CELLS` cells. Beyond them a map is refused with
#: the reason, not planned on.
RESOLUTION_RANGE = (0.001, 1.0)
SIDE_RANGE = (0.01, 1000.0)
ORIGIN_LIMIT = 1e5
#: Cells a map may have at most: the planner holds about 150 bytes per cell (its graph and
#: one cost-to-go field; 4 M cells take 0.6 GB here), so a 350 m square at 5 cm (50 M cells)
#: takes some 7.5 GB. A finer or larger map is refused with the reason, not run out of memory.
MAX_CELLS = 50_000_000
#: Clearance kept from obstacles (m): about half the hexapod's width, legs out.
DEFAULT_INFLATION = 0.25


def default_grid() -> OccupancyGrid:
    """The :data:`DEFAULT_MAP` as a grid."""
    return grid_from_description(obstacles=[], **DEFAULT_MAP)


class MapError(ValueError):
    """A map file or map description that cannot be used, and why."""


def _number(value, name, positive=False):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not math.isfinite(value) or (positive and value <= 0):
        raise MapError(f'{name} must be a finite number{" > 0" if positive else ""}, '
                       f'got {value!r}')
    return float(value)


def check_geometry(resolution, origin, width, height, name='map'):
    """Raise :class:`MapError` unless a map of cell ``resolution``, corner ``origin`` and
    sides ``width`` x ``height`` (m) is within :data:`RESOLUTION_RANGE`, :data:`SIDE_RANGE`
    and :data:`ORIGIN_LIMIT`."""
    def within(value, low, high, what):
        if not low <= value <= high:
            raise MapError(f'{name} {what} {value:g} m is out of [{low:g}, {high:g}] m')
    within(resolution, *RESOLUTION_RANGE, 'resolution')
    for value, what in ((origin[0], 'origin x'), (origin[1], 'origin y')):
        within(value, -ORIGIN_LIMIT, ORIGIN_LIMIT, what)
    within(width, *SIDE_RANGE, 'width')
    within(height, *SIDE_RANGE, 'height')
    cells = math.ceil(width / resolution - 1e-9) * math.ceil(height / resolution - 1e-9)
    if cells > MAX_CELLS:
        raise MapError(f'{name} of {width:g} m x {height:g} m at {resolution:g} m has '
                       f'{cells / 1e6:.0f} M cells, more than the planner holds '
                       f'({MAX_CELLS / 1e6:.0f} M, about 150 bytes each): a coarser '
                       'resolution or a smaller map')


def _numbers(value, name, lengths, what):
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, '__len__'):
        raise MapError(f'{name} must be a list {what}, got {value!r}')
    if len(value) not in lengths:
        raise MapError(f'{name} must be {what}, got {len(value)} number(s): {list(value)!r}')
    return [_number(v, f'{name}[{i}]') for i, v in enumerate(value)]


def grid_from_description(resolution, origin, width, height, obstacles):
    """The project's map description: a ``width`` x ``height`` m field, rectangles occupied.

    ``obstacles`` is a flat list ``[xmin, ymin, xmax, ymax, ...]`` of rectangles in metres;
    a cell is occupied when its centre lies in a rectangle.
    """
    resolution = _number(resolution, 'map.resolution', positive=True)
    x0, y0 = _numbers(origin, 'map.origin', (2,), '[x, y]')
    width = _number(width, 'map.width', positive=True)
    height = _number(height, 'map.height', positive=True)
    check_geometry(resolution, (x0, y0), width, height, 'map.*:')
    if isinstance(obstacles, (str, bytes, dict)) or not hasattr(obstacles, '__len__'):
        raise MapError('map.obstacles must be a flat list of rectangles '
                       f'[xmin, ymin, xmax, ymax, ...] (write [] for none), got {obstacles!r}')
    obstacles = [_number(v, f'map.obstacles[{i}]') for i, v in enumerate(obstacles)]
    if len(obstacles) % 4:
        raise MapError('map.obstacles must be a flat list of rectangles '
                       f'[xmin, ymin, xmax, ymax, ...]; got {len(obstacles)} numbers')
    grid = OccupancyGrid.empty(x0, x0 + width, y0, y0 + height, resolution)
    occupied = grid.occupied.copy()
    ys = grid.origin[1] + (np.arange(grid.height) + 0.5) * grid.resolution
    xs = grid.origin[0] + (np.arange(grid.width) + 0.5) * grid.resolution
    for xmin, ymin, xmax, ymax in np.reshape(obstacles, (-1, 4)):
        if not (xmax > xmin and ymax > ymin):
            raise MapError(f'obstacle [{xmin}, {ymin}, {xmax}, {ymax}] is empty: '
                           'expected xmin < xmax and ymin < ymax')
        occupied[np.ix_((ys >= ymin) & (ys <= ymax), (xs >= xmin) & (xs <= xmax))] = True
    return OccupancyGrid(occupied, grid.resolution, grid.origin)


def grid_from_ros(data, resolution, origin, unknown_is_occupied=True):
    """A grid from ROS occupancy values (``(height, width)``: -1 unknown, 0..100)."""
    data = np.asarray(data)
    if data.ndim != 2 or data.size == 0 or not np.issubdtype(data.dtype, np.integer):
        raise MapError(f'occupancy values must be a non-empty 2-D integer array, got '
                       f'{data.dtype} {data.shape}')
    resolution = _number(resolution, 'resolution', positive=True)
    origin = _numbers(origin, 'origin', (2,), '[x, y]')
    check_geometry(resolution, origin, data.shape[1] * resolution, data.shape[0] * resolution)
    return OccupancyGrid(data, resolution, origin, unknown_is_occupied=unknown_is_occupied)


# --- images ----------------------------------------------------------------------------


def _pgm_tokens(raw, count):
    """The first ``count`` header tokens of a PGM and the offset just after the last one."""
    tokens, i = [], 2
    while len(tokens) < count:
        while i < len(raw) and raw[i:i + 1].isspace():
            i += 1
        if raw[i:i + 1] == b'#':  # a comment runs to the end of the line
            while i < len(raw) and raw[i:i + 1] not in (b'\n', b'\r'):
                i += 1
            continue
        start = i
        while i < len(raw) and not raw[i:i + 1].isspace() and raw[i:i + 1] != b'#':
            i += 1
        if start == i:
            raise MapError('truncated PGM header')
        tokens.append(raw[start:i])
    return tokens, i


def read_pgm(path) -> np.ndarray:
    """Grey levels of a PGM (binary P5 or ASCII P2) scaled to ``[0, 1]``, row 0 on top."""
    with open(path, 'rb') as handle:
        raw = handle.read()
    magic = raw[:2]
    if magic not in (b'P5', b'P2'):
        raise MapError(f'{path}: not a PGM image (starts with {magic!r}, expected P5 or P2)')
    try:
        tokens, end = _pgm_tokens(raw, 3)
        width, height, maxval = (int(t) for t in tokens)
    except ValueError as exc:
        raise MapError(f'{path}: bad PGM header ({exc})') from None
    if width < 1 or height < 1 or not 0 < maxval < 65536:
        raise MapError(f'{path}: bad PGM size {width} x {height} or maxval {maxval}')
    if magic == b'P5':
        dtype = np.dtype('u1') if maxval < 256 else np.dtype('>u2')
        body = raw[end + 1:]  # exactly one whitespace byte ends the header
        need = width * height * dtype.itemsize
        if len(body) < need:
            raise MapError(f'{path}: PGM data truncated ({len(body)} of {need} bytes)')
        values = np.frombuffer(body[:need], dtype=dtype)
    else:
        try:
            values = np.array(raw[end:].split()[:width * height], dtype=np.int64)
        except ValueError:
            raise MapError(f'{path}: PGM data are not integers') from None
        if values.size < width * height:
            raise MapError(f'{path}: PGM data truncated ({values.size} of '
                           f'{width * height} values)')
    return values.reshape(height, width).astype(float) / maxval


def read_image(path):
    """``(shade, alpha)`` of an image, both ``(height, width)`` in ``[0, 1]``, row 0 on top.

    ``shade`` is the mean of the colour channels; ``alpha`` is None for opaque formats. PGM
    is read here; PNG (and anything else Pillow reads) through Pillow, which matplotlib
    brings along.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise MapError(f'map image {path} does not exist')
    if path.lower().endswith('.pgm'):
        return read_pgm(path), None
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover - Pillow comes with matplotlib
        raise MapError(f'{path}: reading this image needs Pillow (pip install pillow)') \
            from None
    try:
        with Image.open(path) as image:
            mode = image.mode
            if mode in ('P', 'PA'):
                image = image.convert('RGBA')
                mode = 'RGBA'
            pixels = np.asarray(image)
    except OSError as exc:
        raise MapError(f'{path}: cannot read the image ({exc})') from None
    scale = 65535.0 if pixels.dtype == np.uint16 or mode.startswith('I') else 255.0
    pixels = pixels.astype(float) / scale
    if pixels.ndim == 2:
        return pixels, None
    alpha = pixels[..., -1] if mode in ('LA', 'RGBA') else None
    colour = pixels[..., :-1] if alpha is not None else pixels
    return colour.mean(axis=-1), alpha


def occupancy_from_image(shade, alpha=None, negate=False, occupied_thresh=0.65,
                         free_thresh=0.25, mode='trinary') -> np.ndarray:
    """map_server's reading of an image: ROS occupancy values, row 0 at the map's origin.

    Returns:
        ``(height, width)`` int8: 100 occupied, 0 free, -1 unknown, and in ``scale`` mode
        the values between; in ``raw`` mode the pixel value itself (0..100, else unknown).
    """
    shade = np.asarray(shade, dtype=float)
    if mode == 'trinary' and alpha is not None:
        # map_server averages the opacity in with the colour channels in trinary mode.
        shade = (shade * 3.0 + (1.0 - np.asarray(alpha, dtype=float))) / 4.0
    occ = shade if negate else 1.0 - shade
    out = np.full(shade.shape, -1, dtype=np.int8)
    if mode == 'raw':
        value = np.rint(shade * 255.0)
        keep = value <= 100
        out[keep] = value[keep].astype(np.int8)
    else:
        occupied, free = occ > occupied_thresh, occ < free_thresh
        if mode == 'scale':
            between = ~occupied & ~free
            out[between] = np.rint((occ[between] - free_thresh)
                                   / (occupied_thresh - free_thresh) * 100.0)
        out[occupied] = 100
        out[free] = 0
        if mode == 'scale' and alpha is not None:
            out[np.asarray(alpha) < 1.0] = -1
    return out[::-1].copy()  # image row 0 is the top (max y); grid row 0 the bottom


# --- files -------------------------------------------------------------------------------


def _read_yaml(path):
    import yaml

    try:
        with open(path) as handle:
            data = yaml.safe_load(handle)
    except OSError as exc:
        raise MapError(f'map file {path}: {exc.strerror}') from exc
    except yaml.YAMLError as exc:
        raise MapError(f'map file {path} is not valid YAML: {exc}') from exc
    if not isinstance(data, dict):
        raise MapError(f'map file {path}: expected a mapping (map_server: image, resolution, '
                       'origin, ...; or resolution, origin, width, height, obstacles)')
    return data


def _map_server_grid(path, data, unknown_is_occupied):
    image = data['image']
    if not isinstance(image, str) or not image:
        raise MapError(f'image must be a file name, got {image!r}')
    if 'resolution' not in data or 'origin' not in data:
        raise MapError('map_server maps need resolution and origin besides image')
    resolution = _number(data['resolution'], 'resolution', positive=True)
    origin = _numbers(data['origin'], 'origin', (2, 3), '[x, y, yaw]')
    if len(origin) == 3 and origin[2] != 0.0:
        raise MapError(f'origin yaw {origin[2]} is not supported: the planner plans in the '
                       'map frame without rotation (save the map with yaw 0)')
    negate = data.get('negate', 0)
    if negate not in (0, 1):  # True/False compare equal to 1/0
        raise MapError(f'negate must be 0 or 1, got {negate!r}')
    occupied_thresh = _number(data.get('occupied_thresh', 0.65), 'occupied_thresh')
    free_thresh = _number(data.get('free_thresh', 0.25), 'free_thresh')
    if not 0.0 <= free_thresh < occupied_thresh <= 1.0:
        raise MapError(f'expected 0 <= free_thresh < occupied_thresh <= 1, got free_thresh '
                       f'{free_thresh}, occupied_thresh {occupied_thresh}')
    mode = data.get('mode', 'trinary')
    if mode not in MAP_SERVER_MODES:
        raise MapError(f'mode must be one of {", ".join(MAP_SERVER_MODES)}, got {mode!r}')
    image_path = image if os.path.isabs(image) else \
        os.path.join(os.path.dirname(os.path.abspath(path)), image)
    shade, alpha = read_image(image_path)
    values = occupancy_from_image(shade, alpha, bool(negate), occupied_thresh, free_thresh,
                                  mode)
    return grid_from_ros(values, resolution, origin[:2], unknown_is_occupied)


def load_map_file(path, unknown_is_occupied=True) -> OccupancyGrid:
    """Read a map YAML in map_server's format (it has ``image``) or the project's own.

    Raises:
        MapError: naming the file and what is wrong in it.
    """
    path = os.fspath(path)
    data = _read_yaml(path)
    try:
        if 'image' in data:
            return _map_server_grid(path, data, unknown_is_occupied)
        missing = {'resolution', 'origin', 'width', 'height'} - set(data)
        if missing:
            raise MapError(f'missing key(s) {sorted(missing)} (expected map_server\'s image, '
                           'resolution, origin... or resolution, origin, width, height, '
                           'obstacles)')
        return grid_from_description(data['resolution'], data['origin'], data['width'],
                                     data['height'], data.get('obstacles', []))
    except MapError as exc:
        if str(exc).startswith(f'map file {path}') or str(exc).startswith(path):
            raise
        raise MapError(f'map file {path}: {exc}') from None
