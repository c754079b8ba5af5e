"""Generated buildings: a hall, a corridor spine and rows of rooms with doors, as a grid.

The scenario generator (``stealth_core.scenario_generator``) needs floors that look like the
buildings guards watch, not noise: a hall at one end of the building, a corridor from it along
the long axis to the far wall, and on each side of the corridor a wing cut into rooms, each
with a door to the corridor; deep wings are cut again into an outer and an inner room (the
inner one reached through the outer); some neighbouring rooms share a door, which makes the
loops a covert route needs. Everything comes from one ``np.random.Generator``.

Decisions:

- **Units**: the plan is laid out in half-metre units (``UNIT``); wall centre lines lie on
  whole units, walls are ``WALL_CELLS`` cells thick (0.2 m at the default 0.1 m cells), doors
  are ``DOOR_UNITS`` units (1.0 m) wide. The robot's move lattice (0.5 m steps) is anchored at
  a unit centre (the generator puts the start there), so two lattice lines pass through every
  door, each 0.25 m from the jambs: more than the robot's 0.2 m radius.
- **Grid**: ``blocked[row, col]``, row 0 the bottom row (smallest y), as
  ``OccupancyMap.data``; the map origin is (0, 0).
- **Long axis**: the corridor runs along x; a building taller than wide is laid out
  transposed and turned back at the end, so rooms, doors and grid agree.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from stealth_core.occupancy_map import FREE, OCCUPIED, OccupancyMap

UNIT = 0.5  # m: the plan's unit, the move lattice's step
DEFAULT_RESOLUTION = 0.1  # m per cell
WALL_CELLS = 2  # wall thickness in cells, centred on a unit line
DOOR_UNITS = 2  # door width in units (1.0 m)
CORRIDOR_UNITS = 4  # corridor width between wall centre lines (2.0 m)
ROOM_UNITS = (6, 13)  # room widths along the corridor, [low, high) units (3 to 6 m)
DEEP_WING_UNITS = 16  # a wing deeper than this (8 m) may be cut into outer and inner rooms
SIDE_DOOR_CHANCE = 0.7  # a door between neighbouring rooms of a wing


@dataclasses.dataclass(frozen=True)
class Room:
    """A rectangle between wall centre lines, in units: x0 < x1, y0 < y1."""

    kind: str  # 'hall', 'corridor' or 'room'
    x0: int
    y0: int
    x1: int
    y1: int

    @property
    def centre(self) -> tuple[float, float]:
        """The centre in metres, moved onto the nearest unit centre (a lattice node)."""
        return (
            ((self.x0 + self.x1) // 2 + 0.5) * UNIT,
            ((self.y0 + self.y1) // 2 + 0.5) * UNIT,
        )

    def contains(self, x: float, y: float) -> bool:
        """Whether the point (m) lies inside the walls' centre lines."""
        return self.x0 * UNIT < x < self.x1 * UNIT and self.y0 * UNIT < y < self.y1 * UNIT

    def transposed(self) -> Room:
        return Room(self.kind, self.y0, self.x0, self.y1, self.x1)


@dataclasses.dataclass(frozen=True)
class Door:
    """An opening through the wall on the unit line ``at`` (vertical wall: x = at, else y =
    at), spanning ``[low, high)`` units along it, between rooms ``a`` and ``b`` (indices)."""

    vertical: bool
    at: int
    low: int
    high: int
    a: int
    b: int

    @property
    def width(self) -> float:
        """The clear opening in metres."""
        return (self.high - self.low) * UNIT

    @property
    def centre(self) -> tuple[float, float]:
        middle = (self.low + self.high) / 2 * UNIT
        return (self.at * UNIT, middle) if self.vertical else (middle, self.at * UNIT)

    def transposed(self) -> Door:
        return Door(not self.vertical, self.at, self.low, self.high, self.a, self.b)


@dataclasses.dataclass(frozen=True, eq=False)
class FloorPlan:
    """A building: its rooms (the hall first, then the corridor), doors and blocked cells."""

    width: float  # m
    height: float  # m
    resolution: float  # m per cell
    rooms: tuple[Room, ...]
    doors: tuple[Door, ...]
    blocked: np.ndarray  # (rows, cols) bool, row 0 the bottom

    @property
    def hall(self) -> int:
        return 0

    @property
    def corridor(self) -> int:
        return 1

    def occupancy_map(self) -> OccupancyMap:
        """The plan as an OccupancyMap (walls occupied, everything else free; origin 0)."""
        data = np.where(self.blocked, OCCUPIED, FREE).astype(np.int8)
        return OccupancyMap(data, self.resolution, (0.0, 0.0, 0.0))

    def doors_of(self, room: int) -> list[Door]:
        return [door for door in self.doors if room in (door.a, door.b)]

    def neighbours(self, room: int) -> list[int]:
        """The rooms one door away."""
        return [door.b if door.a == room else door.a for door in self.doors_of(room)]

    def door_distances(self, room: int) -> list[int]:
        """Doors to pass from ``room`` to each room (breadth first over the door graph)."""
        distance = [-1] * len(self.rooms)
        distance[room] = 0
        frontier = [room]
        while frontier:
            following = []
            for here in frontier:
                for there in self.neighbours(here):
                    if distance[there] < 0:
                        distance[there] = distance[here] + 1
                        following.append(there)
            frontier = following
        return distance


def generate_floor_plan(
    rng: np.random.Generator,
    width: int,
    height: int,
    resolution: float = DEFAULT_RESOLUTION,
) -> FloorPlan:
    """A building of width x height metres (whole metres), laid out along its long axis."""
    if height > width:
        plan = generate_floor_plan(rng, height, width, resolution)
        return FloorPlan(
            float(width),
            float(height),
            resolution,
            tuple(room.transposed() for room in plan.rooms),
            tuple(door.transposed() for door in plan.doors),
            np.ascontiguousarray(plan.blocked.T),
        )
    rooms, doors = _layout(rng, 2 * width, 2 * height)
    if rng.random() < 0.5:  # the hall on the east side as often as on the west
        rooms, doors = _mirrored(rooms, doors, 2 * width)
    blocked = _draw(rooms, doors, 2 * width, 2 * height, resolution)
    return FloorPlan(float(width), float(height), resolution, tuple(rooms), tuple(doors), blocked)


def _layout(rng: np.random.Generator, wide: int, high: int) -> tuple[list[Room], list[Door]]:
    """Rooms and doors in units: hall at x = 0, the corridor to the east, two wings."""
    hall_width = int(rng.integers(10, 17))
    hall_width = min(hall_width, max(wide // 3, 8))
    low = max(round(0.35 * high), 6)
    top = max(round(0.65 * high) - CORRIDOR_UNITS, low + 1)
    corridor_y = int(rng.integers(low, top))
    rooms = [
        Room('hall', 0, 0, hall_width, high),
        Room('corridor', hall_width, corridor_y, wide, corridor_y + CORRIDOR_UNITS),
    ]
    # The corridor opens into the hall over its whole width (no door, no wall).
    doors = [Door(True, hall_width, corridor_y, corridor_y + CORRIDOR_UNITS, 0, 1)]
    for wing_low, wing_high, corridor_side in (
        (0, corridor_y, corridor_y),
        (corridor_y + CORRIDOR_UNITS, high, corridor_y + CORRIDOR_UNITS),
    ):
        _wing(rng, rooms, doors, hall_width, wide, wing_low, wing_high, corridor_side)
    return rooms, doors


def _wing(rng, rooms, doors, x_low, x_high, y_low, y_high, corridor_side) -> None:
    """Cut one wing into a row of rooms along the corridor, some of them outer + inner."""
    columns = []
    x = x_low
    while x < x_high:
        step = int(rng.integers(*ROOM_UNITS))
        if x_high - (x + step) < ROOM_UNITS[0]:
            step = x_high - x
        columns.append((x, x + step))
        x += step
    depth = y_high - y_low
    previous: list[tuple[int, int, int]] = []  # (room, y0, y1) of the column to the west
    for x0, x1 in columns:
        cut = depth > DEEP_WING_UNITS and rng.random() < 0.7
        if cut:
            split = int(rng.integers(y_low + 6, y_high - 5))
            parts = [(y_low, split), (split, y_high)]
        else:
            parts = [(y_low, y_high)]
        here = []
        for y0, y1 in parts:
            rooms.append(Room('room', x0, y0, x1, y1))
            here.append((len(rooms) - 1, y0, y1))
        outer = next(r for r in here if corridor_side in (r[1], r[2]))
        doors.append(_door(rng, False, corridor_side, x0, x1, 1, outer[0]))
        for inner in (r for r in here if r is not outer):
            line = inner[2] if inner[2] == outer[1] else inner[1]
            doors.append(_door(rng, False, line, x0, x1, outer[0], inner[0]))
        west = previous or [(0, y_low, y_high)]  # the hall, at the wing's west end
        for room, y0, y1 in here:
            for other, w0, w1 in west:
                low, high = max(y0, w0), min(y1, w1)
                if high - low >= DOOR_UNITS + 2 and rng.random() < SIDE_DOOR_CHANCE:
                    doors.append(_door(rng, True, x0, low, high, other, room))
        previous = here


def _door(rng, vertical: bool, at: int, low: int, high: int, a: int, b: int) -> Door:
    """A door somewhere along the wall segment [low, high), a unit clear of each end."""
    start = int(rng.integers(low + 1, high - DOOR_UNITS))
    return Door(vertical, at, start, start + DOOR_UNITS, a, b)


def _mirrored(rooms, doors, wide: int) -> tuple[list[Room], list[Door]]:
    rooms = [Room(r.kind, wide - r.x1, r.y0, wide - r.x0, r.y1) for r in rooms]
    doors = [
        Door(True, wide - d.at, d.low, d.high, d.a, d.b)
        if d.vertical
        else Door(False, d.at, wide - d.high, wide - d.low, d.a, d.b)
        for d in doors
    ]
    return rooms, doors


def _draw(rooms, doors, wide: int, high: int, resolution: float) -> np.ndarray:
    """The blocked grid: every room's outline as walls, then the doors cut through them."""
    per_unit = UNIT / resolution
    cols, rows = round(wide * per_unit), round(high * per_unit)
    blocked = np.zeros((rows, cols), dtype=bool)
    half = WALL_CELLS // 2

    def line(at: int, size: int) -> slice:
        centre = round(at * per_unit)
        return slice(min(max(centre - half, 0), size - WALL_CELLS), max(centre + half, WALL_CELLS))

    def span(low: int, high: int) -> slice:
        return slice(round(low * per_unit), round(high * per_unit))

    for room in rooms:
        for at in (room.x0, room.x1):
            blocked[span(room.y0, room.y1), line(at, cols)] = True
        for at in (room.y0, room.y1):
            blocked[line(at, rows), span(room.x0, room.x1)] = True
    for door in doors:
        if door.vertical:
            blocked[span(door.low, door.high), line(door.at, cols)] = False
        else:
            blocked[line(door.at, rows), span(door.low, door.high)] = False
    # The corridor's mouth cut the corners where the corridor's walls meet the hall's: close them.
    corridor = rooms[1]
    mouth = line(corridor.x0 if doors[0].at == corridor.x0 else corridor.x1, cols)
    for at in (corridor.y0, corridor.y1):
        blocked[line(at, rows), mouth] = True
    return blocked
