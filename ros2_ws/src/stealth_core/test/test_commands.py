"""The commands stealth_core adds to `stealth` (render, scenarios), registered in the entry-point
group that `stealth` reads, so the tools need not import this package."""

from importlib.metadata import entry_points

from stealth_core.commands import COMMANDS


def test_the_entry_point_group_holds_stealth_cores_commands():
    (entry,) = [e for e in entry_points(group='stealth.commands') if e.name == 'stealth_core']
    assert entry.load() == COMMANDS
    assert list(COMMANDS) == ['render', 'scenarios']
    assert not [e for e in entry_points(group='stealth.commands') if e.name == 'stealth_env']
