"""stealth_core: installable the ament way (colcon) and with pip, with no ROS at all.

pip users get the repository's shipped scenarios and maps inside the package
(``stealth_core/data``): a wheel cannot reach the files beside the workspace, so the build copies
them in; a colcon symlink install reads them where they are.
"""

from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

package_name = 'stealth_core'
REPOSITORY = Path(__file__).resolve().parents[3]
# (repository folder, file patterns): what a scenario needs, its maps beside it as '../maps/'.
SHIPPED = (('scenarios', ('*.yaml',)), ('maps', ('*.yaml', '*.pgm')))


class BuildWithScenarios(build_py):
    """build_py that also copies the shipped scenarios and maps into stealth_core/data."""

    def run(self):
        super().run()
        for folder, patterns in SHIPPED:
            target = Path(self.build_lib) / package_name / 'data' / folder
            for pattern in patterns:
                for source in sorted((REPOSITORY / folder).glob(pattern)):
                    target.mkdir(parents=True, exist_ok=True)
                    self.copy_file(str(source), str(target / source.name))


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    cmdclass={'build_py': BuildWithScenarios},
    python_requires='>=3.11',
    # Exact versions live in the repository's requirements.lock (pip install -c it).
    install_requires=[
        'setuptools',
        'numpy',
        'numba',
        'PyYAML',
        'opencv-python-headless',
        'matplotlib',
        'pillow',
        'gymnasium',
    ],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='stealth-nav developers',
    maintainer_email='dev@stealth-nav.org',
    description=(
        'The world model of stealth-nav without ROS: searchlights, occlusion, rewards, '
        'planners, scenarios and the Gymnasium environment StealthNav-v0.'
    ),
    license='Apache-2.0',
    # No console script of its own (a pip install would put a bare `render` on PATH): the
    # `stealth` command finds `render` and `scenarios` here; without it, python -m
    # stealth_core.render and python -m stealth_core.scenario_commands.
    entry_points={'stealth.commands': ['stealth_core = stealth_core.commands:COMMANDS']},
)
