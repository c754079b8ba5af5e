"""Small hand-made maps for the simulator tests (not a test module), and the project's own maps.

``room`` is a rectangle of free space inside a ring of occupied cells one cell thick, so every
wall position is known exactly: the free interior spans
``[origin + res, origin + (cells - 1) * res]`` on both axes.
"""

import math
from pathlib import Path

import numpy as np
from stealth_core.kinematics import Pose
from stealth_core.occupancy_map import FREE, OCCUPIED, UNKNOWN, OccupancyMap, load_map
from stealth_core.scenario import load_scenario
from stealth_sim.simulator import most_open_pose

RESOLUTION = 0.05
REPO_ROOT = Path(__file__).resolve().parents[4]
PROJECT_MAPS = ('lgfloor', 'map1', 'floorplan', 'simple-maze')


def room(cols: int = 100, rows: int = 60) -> np.ndarray:
    """Cells (row 0 = bottom) of a free room with a one-cell occupied ring."""
    data = np.full((rows, cols), FREE, np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = OCCUPIED
    return data


def as_map(data: np.ndarray) -> OccupancyMap:
    """Cells at the test resolution with the origin at (0, 0)."""
    return OccupancyMap(data, RESOLUTION, (0.0, 0.0, 0.0))


def maze_map() -> OccupancyMap:
    """A 10 x 8 m floor with rooms, doors, furniture and an unknown patch: enough structure
    to localise in, and always available (the project's maps may not be built yet)."""
    data = room(200, 160)
    data[80, 1:199] = OCCUPIED  # a wall across the middle with two doors
    data[80, 30:50] = FREE
    data[80, 140:160] = FREE
    data[1:80, 100] = OCCUPIED  # the south half split in two, a door between
    data[30:50, 100] = FREE
    data[110:130, 20:40] = OCCUPIED  # furniture
    data[20:28, 150:190] = OCCUPIED
    data[120:150, 120:140] = UNKNOWN  # a room never mapped
    return as_map(data)


def project_map_and_start(name: str) -> tuple[OccupancyMap, Pose] | None:
    """A shipped map and its scenario's start, or None when the map is not built.

    Without a scenario the start is the map's most open point.
    """
    map_path = REPO_ROOT / 'maps' / f'{name}.yaml'
    if not map_path.is_file():
        return None
    occupancy_map = load_map(map_path)
    return occupancy_map, scenario_start(name) or most_open_pose(occupancy_map)


def scenario_start(name: str) -> Pose | None:
    """The start of ``scenarios/<name>.yaml``, read by stealth_core (the scenario format is the
    world model's business)."""
    path = REPO_ROOT / 'scenarios' / f'{name}.yaml'
    if not path.is_file():
        return None
    x, y, yaw = load_scenario(path).start
    return Pose(float(x), float(y), float(yaw))


def angle_error(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))
