"""Point the ROS wheels' exported CMake files at this machine's Python and numpy headers.

The ros-jazzy-* wheels are built in a manylinux container, and the CMake export files of every
message package keep that container's include paths (/opt/python/cp311-cp311/...). CMake refuses
to configure an interface package that depends on them unless the paths exist, so after installing
the wheels we rewrite them to the venv's own interpreter headers. It also gives the venv the
`local_setup.sh` colcon expects of every prefix on AMENT_PREFIX_PATH (empty: scripts/ros_env.sh
sets the venv's environment). Idempotent.
"""

import pathlib
import sys
import sysconfig

import numpy

BUILD_PREFIX = '/opt/python/cp311-cp311'
BUILD_PYTHON_INCLUDE = f'{BUILD_PREFIX}/include/python3.11'
BUILD_NUMPY_INCLUDE = f'{BUILD_PREFIX}/lib/python3.11/site-packages/numpy/_core/include'


def main() -> int:
    venv = pathlib.Path(sys.prefix)
    python_include = sysconfig.get_paths()['include']
    if not pathlib.Path(python_include, 'Python.h').is_file():
        print(
            f'error: no Python.h in {python_include}: install the Python 3.11 development '
            'headers (Debian: apt-get install python3.11-dev)',
            file=sys.stderr,
        )
        return 1
    replacements = {
        BUILD_NUMPY_INCLUDE: numpy.get_include(),
        BUILD_PYTHON_INCLUDE: python_include,
    }
    fixed = 0
    for path in venv.glob('share/*/cmake/*.cmake'):
        text = path.read_text()
        if BUILD_PREFIX not in text:
            continue
        for old, new in replacements.items():
            text = text.replace(old, new)
        path.write_text(text)
        fixed += 1
    local_setup = venv / 'local_setup.sh'
    if not local_setup.exists():
        local_setup.write_text('# The environment of this prefix is set by scripts/ros_env.sh.\n')
    print(f'fix_ros_wheels: rewrote build-container include paths in {fixed} CMake files')
    return 0


if __name__ == '__main__':
    sys.exit(main())
