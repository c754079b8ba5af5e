"""`stealth scenarios`: generate proven scenarios (``stealth_core.scenario_generator``) and draw a
contact sheet of a directory of them.

    stealth scenarios generate --seed 0 --count 20 --out gen/ [--width 30 --height 30 --lights 4
        --moving none --difficulty medium --contact-sheet gen.png]
    stealth scenarios sheet gen/ --out gen.png

Scenario k of a batch has the seed ``seed + k`` and is named by it (``gen-0000042.yaml``, its
map in ``maps/``). Every failure is one line on stderr and exit status 1; the outputs (--out,
--contact-sheet) are checked before anything is generated or drawn; a batch stops at the first
seed that gives no proven scenario, keeping the ones written before it.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import math
from pathlib import Path
import sys
import tempfile

import numpy as np

from stealth_core.guard_lights import MOVING
from stealth_core.scenario import DIFFICULTIES, ScenarioError, load_scenario
from stealth_core.scenario_generator import (
    HEIGHT_RANGE,
    LIGHTS_RANGE,
    SEED_RANGES,
    WIDTH_RANGE,
    GenerationError,
    Options,
    generate,
    seed_range_of,
)

SHEET_COLUMNS = 4
SHEET_LIMIT = 24  # scenarios drawn on one sheet at most
COUNT_LIMIT = 100_000


def _seed_ranges() -> str:
    parts = []
    for name, (low, high) in SEED_RANGES.items():
        parts.append(f'{name} {low:,}-{high:,}' if high is not None else f'{name} {low:,} and up')
    return '; '.join(parts)


def parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(
        prog='stealth scenarios',
        description='Generate proven scenarios in buildings nobody drew, and draw them.',
    )
    verbs = top.add_subparsers(dest='verb', required=True, metavar='{generate,sheet}')
    make = verbs.add_parser(
        'generate',
        help='write COUNT proven scenarios (maps and scenario YAMLs) into a new directory',
        description=(
            'Write COUNT scenarios, seeds SEED to SEED + COUNT - 1, into OUT: each a building '
            "(hall, corridor, rooms, doors), guards' lights and a goal, proven on generation "
            '(a covert route exists within the step limit; the shortest route ignoring the '
            'lights is seen). The same seed and options give the same files byte for byte. '
            f'Seed ranges: {_seed_ranges()}. Tune only on train and validation seeds: the '
            'test range is for final results only.'
        ),
    )
    make.add_argument('--seed', type=int, required=True, help="the first scenario's seed (>= 0)")
    make.add_argument('--count', type=int, default=1, help='scenarios to write (default 1)')
    make.add_argument('--out', type=Path, required=True, help='a new or empty directory')
    make.add_argument(
        '--width', type=int, default=30, help=f'm, {WIDTH_RANGE[0]}-{WIDTH_RANGE[1]} (default 30)'
    )
    make.add_argument(
        '--height',
        type=int,
        default=30,
        help=f'm, {HEIGHT_RANGE[0]}-{HEIGHT_RANGE[1]} (default 30)',
    )
    make.add_argument(
        '--lights',
        type=int,
        default=4,
        help=f'searchlights, {LIGHTS_RANGE[0]}-{LIGHTS_RANGE[1]} (default 4)',
    )
    make.add_argument(
        '--moving', default='none', help=f'moving lights: {", ".join(MOVING)} (default none)'
    )
    make.add_argument(
        '--difficulty',
        default='medium',
        help=f"{', '.join(DIFFICULTIES)} (default medium): the lights' reach and how many "
        "guard the goal's approach; hard also wants a covert route >= 1.1 x the shortest",
    )
    make.add_argument('--contact-sheet', type=Path, help='also draw the batch to this PNG')
    sheet = verbs.add_parser('sheet', help='draw the scenarios of a directory on one PNG')
    sheet.add_argument('directory', type=Path, help='a directory of scenario YAMLs')
    sheet.add_argument('--out', type=Path, required=True, help='the PNG to write')
    return top


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        if args.verb == 'generate':
            return _generate(args)
        paths = scenario_files(args.directory)
        check_sheet_path(args.out, '--out')
        print(f'contact sheet: {contact_sheet(paths, args.out)}')
        return 0
    except (GenerationError, ScenarioError, OSError) as error:
        print(f'stealth scenarios: {error}', file=sys.stderr)
        return 1


def _generate(args) -> int:
    options = Options(args.width, args.height, args.lights, args.moving, args.difficulty)
    options.check()
    if not 1 <= args.count <= COUNT_LIMIT:
        raise GenerationError(
            f'--count: expected a whole number in [1, {COUNT_LIMIT}], got {args.count}'
        )
    if args.seed < 0:
        raise GenerationError(f'--seed: expected a whole number >= 0, got {args.seed}')
    last = args.seed + args.count - 1
    if seed_range_of(args.seed) != seed_range_of(last):
        raise GenerationError(
            f'--seed {args.seed} --count {args.count}: seeds {args.seed}-{last} cross a seed '
            f'range boundary ({_seed_ranges()}); generate each range separately'
        )
    out = args.out
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise GenerationError(
            f'--out {out}: exists and is not an empty directory; give a new or empty directory '
            '(generated files never overwrite others)'
        )
    check_writable(out, '--out')
    if args.contact_sheet is not None:
        check_sheet_path(args.contact_sheet, '--contact-sheet')
    paths = []
    for seed in range(args.seed, last + 1):
        generated = generate(seed, options)
        paths.append(generated.write(out))
        proof = generated.proof
        print(
            f'{paths[-1]}: shortest {proof.shortest_steps} steps (seen), covert '
            f'{proof.covert_steps} steps, {100 * proof.lit:.1f} % lit, try {proof.tries}'
        )
    print(f'{len(paths)} scenarios in {out} ({seed_range_of(args.seed) or "no"} seed range)')
    if args.contact_sheet is not None:
        print(f'contact sheet: {contact_sheet(paths, args.contact_sheet)}')
    return 0


def scenario_files(directory: Path) -> list[Path]:
    """The scenario YAMLs of a directory, in order; GenerationError saying why there are none."""
    if not directory.exists():
        raise GenerationError(f'{directory}: no such directory')
    if not directory.is_dir():
        raise GenerationError(f'{directory}: is not a directory (give a directory of scenarios)')
    paths = sorted(directory.glob('*.yaml'))
    if not paths:
        raise GenerationError(f'{directory}: no scenario YAMLs (*.yaml) in it')
    return paths


def check_sheet_path(out: Path, option: str) -> None:
    """A contact sheet can be written to `out` (a .png file name, in a directory this user can
    write or create), or GenerationError naming why not, before anything is drawn."""
    if out.suffix.lower() != '.png':
        raise GenerationError(f'{option} {out}: expected a .png file name')
    if out.is_dir():
        raise GenerationError(f'{option} {out}: is a directory (give a .png file name)')
    check_writable(out, option)


def check_writable(path: Path, option: str) -> None:
    """What this command writes at `path` (a file or directory it makes, with any missing
    parent, or an empty directory it fills) can be written: the directory it goes in, or its
    nearest existing parent, takes a file. GenerationError naming the directory and why not."""
    parent = path.absolute() if path.is_dir() else path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise GenerationError(f'{option} {path}: {parent} is not a directory')
    try:
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError as error:
        raise GenerationError(
            f'{option} {path}: directory {parent} is not writable ({error.strerror})'
        ) from None


def contact_sheet(paths: Sequence[Path], out: Path) -> Path:
    """Draw up to SHEET_LIMIT scenarios (scenario_drawing's figure of each, with its covert
    route) in a grid of SHEET_COLUMNS on one PNG."""
    import cv2

    from stealth_core.planners import optimal_path
    from stealth_core.scenario_drawing import figure_pixels, scenario_figure

    paths = list(paths)[:SHEET_LIMIT]
    if not paths:
        raise GenerationError('contact sheet: no scenario YAMLs to draw')
    tiles = []
    for path in paths:
        scenario = load_scenario(path)
        points, _ = optimal_path(scenario, None)
        figure = scenario_figure(
            scenario, paths=[points], path_labels=['covert route'], title=scenario.name, dpi=40
        )
        tiles.append(figure_pixels(figure))
    height = max(tile.shape[0] for tile in tiles)
    width = max(tile.shape[1] for tile in tiles)
    columns = min(SHEET_COLUMNS, len(tiles))
    rows = math.ceil(len(tiles) / columns)
    sheet = np.full((rows * height, columns * width, 3), 255, dtype=np.uint8)
    for index, tile in enumerate(tiles):
        row, column = divmod(index, columns)
        sheet[
            row * height : row * height + tile.shape[0],
            column * width : column * width + tile.shape[1],
        ] = tile
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out), sheet[..., ::-1]):
        raise GenerationError(f'{out}: cannot write the contact sheet')
    return out


if __name__ == '__main__':
    sys.exit(main())
