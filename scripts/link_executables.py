#!/usr/bin/env python3
"""Mirror sela_ros's console scripts into <prefix>/lib/sela_ros/, where `ros2 run` looks.

colcon builds ament_python packages with setup.cfg's `install_scripts=$base/lib/sela_ros`;
pip ignores that option and puts console scripts in <prefix>/bin/. After `pip install .`
into the project's .venv this script links each declared console script into
<prefix>/lib/sela_ros/ so that the ament index prefix of sela_ros holds the executables
exactly where a ROS install would.
"""
import argparse
import os
import sys
from importlib import metadata
from pathlib import Path


def declared_console_scripts(dist_name='sela_ros'):
    dist = metadata.distribution(dist_name)
    return sorted(ep.name for ep in dist.entry_points if ep.group == 'console_scripts')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--prefix', default=sys.prefix,
                        help='install prefix (default: %(default)s)')
    args = parser.parse_args(argv)
    prefix = Path(args.prefix).resolve()
    bin_dir = prefix / 'bin'
    lib_dir = prefix / 'lib' / 'sela_ros'
    lib_dir.mkdir(parents=True, exist_ok=True)
    for name in declared_console_scripts():
        source = bin_dir / name
        if not source.exists():
            sys.exit(f'link_executables: {source} is missing: is sela_ros installed in {prefix}?')
        target = lib_dir / name
        if target.is_symlink() or target.exists():
            target.unlink()
        os.symlink(os.path.relpath(source, lib_dir), target)
    print(f'link_executables: {len(declared_console_scripts())} executables in {lib_dir}')


if __name__ == '__main__':
    main()
