"""Searchlights placed as guards would place them in a generated building.

Guards watch what an intruder must pass: the doors of the room being guarded (the goal's),
the corridor along its length, the hall where the corridor opens, and other doors. Each light
is a *post*: a lamp standing in a free cell a little off the walls, aimed at what it watches.
The first post of every difficulty watches the goal's approach: a lamp in the corridor beside
the corridor door nearest the goal's room, aimed back along the corridor (so the shortest way,
down the corridor, is seen); then, by difficulty (hard: the goal room's doors and both
corridor ends; medium: one of the goal room's doors and one corridor end; easy: other doors
and the hall), then doors at random, until the count. One
door of the goal's room is never watched from a post aimed at it: a room whose every door is
watched has no covert way in.

Moving lights (``MOVING``): a sweeping light turns back and forth over a sector centred on its
post's aim; a patrolling light travels a rail (``RAIL_LENGTHS``: 6 m, or 3 m where 6 do not fit)
along the corridor (or across
the hall) and back. Every period is ``PERIOD`` s, so the lights' joint cycle is ``PERIOD`` s,
split into ``PHASE_BINS`` bins of ``STEP_SECONDS`` s: exact under ``stealth_core.light_cycle``'s
rules (each period and the step a whole number of bins) with the shipped moving scenarios'
3 s step. Sweep spans are whole multiples of 6 degrees, so the angular speed (span / 12
degrees/s) is written exactly.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from stealth_core.floor_plan import UNIT, Door, FloorPlan, Room

MOVING = ('none', 'sweeping', 'patrolling', 'mixed')
PERIOD = 24.0  # s: every moving light's period, so the joint cycle
PHASE_BINS = 8
STEP_SECONDS = 3.0  # s per move or wait: one bin
RAIL_LENGTHS = (6.0, 3.0)  # m: the rails a patrol may have, the longest that fits
INSET = 0.35  # m from a wall's centre line to a lamp (the wall's face is 0.1 m from it)
MIN_SPACING = 1.5  # m between two lamps
# Per difficulty: (range low, high) m and (fov low, high) degrees of the lights.
LIGHT_SIZES = {
    'easy': ((4.0, 6.0), (30, 50)),
    'medium': ((5.0, 8.0), (40, 60)),
    'hard': ((7.0, 10.0), (50, 80)),
}


@dataclasses.dataclass(frozen=True)
class Post:
    """Where a guard's lamp stands (m) and what it is aimed at (degrees, from +x)."""

    kind: str  # 'approach', 'goal', 'corridor', 'hall' or 'door'
    x: float
    y: float
    direction: float
    rail: tuple[float, float] | None = None  # where a patrol from here goes (m), if anywhere
    rail_length: float = 0.0  # m, one of RAIL_LENGTHS


def place_lights(
    rng: np.random.Generator,
    plan: FloorPlan,
    goal_room: int,
    count: int,
    moving: str,
    difficulty: str,
) -> list[dict]:
    """``count`` lights as scenario-file mappings (name, x, y, direction, fov, range, delta
    and, for moving ones, motion), in the order they were posted."""
    posts = _posts(rng, plan, goal_room, difficulty)
    chosen: list[Post] = []
    for post in posts:
        if all(math.dist((post.x, post.y), (c.x, c.y)) >= MIN_SPACING for c in chosen):
            chosen.append(post)
        if len(chosen) == count:
            break
    (range_low, range_high), (fov_low, fov_high) = LIGHT_SIZES[difficulty]
    motions = _motions(rng, chosen, moving)
    lights = []
    for number, (post, motion) in enumerate(zip(chosen, motions, strict=True), start=1):
        light = {
            'name': f'{post.kind}-{number}',
            'x': round(post.x, 3),
            'y': round(post.y, 3),
            'direction': round(post.direction) % 360,
            'fov': int(rng.integers(fov_low, fov_high + 1)),
            'range': round(float(rng.uniform(range_low, range_high)), 1),
            'delta': 0.1,
        }
        if motion is not None:
            light['motion'] = motion
        lights.append(light)
    return lights


def _motions(rng: np.random.Generator, posts: list[Post], moving: str) -> list[dict | None]:
    """Each post's motion mapping (None: static) for the ``moving`` option."""
    motions: list[dict | None] = [None] * len(posts)
    if moving == 'none' or not posts:
        return motions
    patrols = [i for i, post in enumerate(posts) if post.rail is not None]
    if moving in ('patrolling', 'mixed') and patrols:
        wanted = 1 if moving == 'mixed' or len(posts) < 5 else 2
        for i in patrols[:wanted]:
            end = posts[i].rail
            motions[i] = {
                'type': 'patrol',
                'waypoints': [[round(end[0], 3), round(end[1], 3)]],
                'speed': 2 * posts[i].rail_length / PERIOD,  # 0.5 or 0.25 m/s: exact
            }
    if moving in ('sweeping', 'mixed'):
        still = [i for i, motion in enumerate(motions) if motion is None]
        sweepers = still if moving == 'sweeping' else still[::2]
        for i in sweepers[: max(1, len(still) // 2) if moving == 'sweeping' else None]:
            span = 6 * int(rng.integers(7, 17))  # 42 to 96 degrees
            aim = round(posts[i].direction) % 360
            motions[i] = {
                'type': 'sweep',
                'min_direction': aim - span // 2,
                'max_direction': aim + span // 2,
                'angular_speed': span / (PERIOD / 2),
            }
    return motions


def _posts(rng: np.random.Generator, plan: FloorPlan, goal_room: int, difficulty: str):
    """Candidate posts, most important first for the difficulty."""
    corridor = plan.rooms[plan.corridor]
    goal = [_watch_door(rng, plan, door, away_from=goal_room) for door in plan.doors_of(goal_room)]
    goal = goal[:-1]  # one way in stays unwatched: a room watched at every door has no covert way
    ends = _corridor_posts(rng, plan, corridor)
    hall = [_hall_post(rng, plan)]
    others = [door for door in plan.doors if goal_room not in (door.a, door.b)]
    order = rng.permutation(len(others))
    doors = [_watch_door(rng, plan, others[i]) for i in order]
    approach = [_approach_post(plan, goal_room)]
    if difficulty == 'hard':
        return approach + goal + ends + doors + hall
    if difficulty == 'medium':
        return approach + goal[:1] + ends[:1] + doors + hall + ends[1:] + goal[1:]
    return approach + doors[:2] + hall + doors[2:] + ends


def _approach_post(plan: FloorPlan, goal_room: int) -> Post:
    """A lamp in the corridor beside the door nearest the goal's room, aimed back along the
    corridor towards the hall: whoever comes down the corridor to that door walks into it."""
    corridor = plan.rooms[plan.corridor]
    along_x = corridor.x1 - corridor.x0 >= corridor.y1 - corridor.y0
    distance = plan.door_distances(goal_room)
    doors = [d for d in plan.doors[1:] if plan.corridor in (d.a, d.b)]
    door = min(doors, key=lambda d: distance[d.b if d.a == plan.corridor else d.a])
    mouth = plan.doors[0].centre
    (dx, dy), (mx, my) = door.centre, mouth
    if along_x:
        y = (corridor.y0 + corridor.y1) / 2 * UNIT + 0.25
        x = dx + math.copysign(0.75, dx - mx)
        return Post('approach', x, y, 0.0 if mx > x else 180.0)
    x = (corridor.x0 + corridor.x1) / 2 * UNIT + 0.25
    y = dy + math.copysign(0.75, dy - my)
    return Post('approach', x, y, 90.0 if my > y else 270.0)


def _corridor_posts(rng: np.random.Generator, plan: FloorPlan, corridor: Room) -> list[Post]:
    """A lamp at each end of the corridor aimed along it, the first one on a rail."""
    along_x = corridor.x1 - corridor.x0 >= corridor.y1 - corridor.y0
    low, high = (corridor.x0, corridor.x1) if along_x else (corridor.y0, corridor.y1)
    middle = ((corridor.y0 + corridor.y1) if along_x else (corridor.x0 + corridor.x1)) / 2 * UNIT
    middle += 0.25  # on a lattice line: a rail down the corridor's middle
    posts = []
    for end, aim in ((low * UNIT + INSET, 0.0), (high * UNIT - INSET, 180.0)):
        length = _rail_length((high - low) * UNIT - 2 * INSET)
        target = end + (length if aim == 0.0 else -length)
        if along_x:
            post = Post('corridor', end, middle, aim, (target, middle) if length else None, length)
        else:
            rail = (middle, target) if length else None
            post = Post('corridor', middle, end, aim + 90.0, rail, length)
        posts.append(post)
    if rng.random() < 0.5:
        posts.reverse()
    return posts


def _hall_post(rng: np.random.Generator, plan: FloorPlan) -> Post:
    """A lamp in a corner of the hall aimed at the corridor's mouth, on a rail along the wall
    towards the hall's other side."""
    hall = plan.rooms[plan.hall]
    mouth = plan.doors[0].centre  # the corridor's mouth
    corners = _corners(hall)
    x, y = corners[int(rng.integers(len(corners)))]
    length = _rail_length((hall.x1 - hall.x0) * UNIT - 2 * INSET)
    inwards = 1.0 if x < (hall.x0 + hall.x1) / 2 * UNIT else -1.0
    rail = (x + inwards * length, y) if length else None
    return Post('hall', x, y, _aim(x, y, *mouth), rail, length)


def _rail_length(room: float) -> float:
    """The longest of RAIL_LENGTHS within ``room`` m; 0 when none fits."""
    return next((length for length in RAIL_LENGTHS if length <= room), 0.0)


def _watch_door(
    rng: np.random.Generator, plan: FloorPlan, door: Door, away_from: int | None = None
) -> Post:
    """A lamp in a corner of one of the door's rooms (not ``away_from``) aimed at the door."""
    sides = [room for room in (door.a, door.b) if room != away_from]
    room = plan.rooms[sides[int(rng.integers(len(sides)))]]
    corners = _corners(room)
    cx, cy = door.centre
    # The corner farthest from the door sees it from across the room.
    x, y = max(corners, key=lambda c: (c[0] - cx) ** 2 + (c[1] - cy) ** 2)
    kind = 'goal' if away_from is not None else 'door'
    return Post(kind, x, y, _aim(x, y, cx, cy))


def _corners(room: Room) -> list[tuple[float, float]]:
    """The lamp positions in a room's four corners, INSET from its walls' centre lines."""
    xs = (room.x0 * UNIT + INSET, room.x1 * UNIT - INSET)
    ys = (room.y0 * UNIT + INSET, room.y1 * UNIT - INSET)
    return [(x, y) for x in xs for y in ys]


def _aim(x: float, y: float, tx: float, ty: float) -> float:
    return math.degrees(math.atan2(ty - y, tx - x)) % 360.0
