"""What each experiment worker process loads once and keeps: the archive, the damage
priors of a run, and the map with its planner (the hexapod experiment's jobs run many
replicates per process)."""
from __future__ import annotations


def load_priors(value, archive_path, archive, damage=None, leave_out_own=False):
    """The damage priors of a run (None: the intact map only); ``leave_out_own`` measures
    ``damage`` as if nobody foresaw it: its own table leaves them, and so do its near
    duplicates in the second tier (the library's tables; the first tier's whole tables of
    other damages stay). Raises DamagePriorError."""
    from sela_ros.core.learning import resolve_priors

    priors = resolve_priors(value, archive_path, archive.params)
    if priors is not None and leave_out_own:
        second = set(priors.names[len(priors.first_tier()):])
        own = own_tables(priors, damage)
        for name in _and_near(priors, own):
            if name in own or name in second:
                priors = priors.without(name)
    return priors


def own_tables(priors, damage):
    """The names of the tables of ``priors`` that are ``damage`` (canonically)."""
    from sim_bridge.damage import parse_damage

    def canonical(name):
        try:
            return parse_damage(name).canonical()
        except ValueError:  # a table that is no damage of the grammar is never its own
            return None

    key = parse_damage(damage).canonical()
    return [n for n in priors.names if canonical(n) == key]


def own_and_near(priors, damage):
    """The names of the tables of ``priors`` that are ``damage`` and of those within
    :data:`NEAR_DUPLICATE` of one of them (``DamagePriors.near``), in the priors' order."""
    return _and_near(priors, own_tables(priors, damage))


def _and_near(priors, names):
    """``names`` and the tables near each (``DamagePriors.near``), in the priors' order."""
    out = {n for name in names for n in priors.near(name)}
    return [n for n in priors.names if n in out]


# Per worker process: the archive, the damage priors and the map, loaded once.
_WORKER = {}


def worker_archive(archive_path):
    """The archive at ``archive_path``, loaded once per worker."""
    from sela_ros.core.storage import load_archive

    if _WORKER.get('path') != archive_path:
        _WORKER['path'] = archive_path
        _WORKER['archive'] = load_archive(archive_path)
    return _WORKER['archive']


def worker_priors(value, archive_path, damage, leave_out_own):
    """:func:`load_priors` for a run, once per worker and setting."""
    key = (value, archive_path, damage, leave_out_own)
    if _WORKER.get('priors_key') != key:
        _WORKER['priors_key'] = key
        _WORKER['priors'] = load_priors(value, archive_path, worker_archive(archive_path),
                                        damage, leave_out_own)
    return _WORKER['priors']


def worker_planner(map_path, inflation):
    """``(grid, planner)`` for a map (None: the planner node's default map), built once per
    worker (its fields are kept too)."""
    from sela_ros.core.planning import GridPlanner, default_grid, load_map_file

    if _WORKER.get('map') != (map_path, inflation):
        grid = load_map_file(map_path) if map_path else default_grid()
        _WORKER['map'] = (map_path, inflation)
        _WORKER['planner'] = (grid, GridPlanner(grid, inflation=inflation))
    return _WORKER['planner']
