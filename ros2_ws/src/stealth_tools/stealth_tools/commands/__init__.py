"""The commands of `stealth` this package defines, one module per command as ros2cli has one
package per command: each module's ``add_parser(commands)`` adds its parser (and its verbs) and
sets each parser's ``handler``, a function of the parsed arguments returning the exit status.

Handlers import their implementation (and rclpy) only when they run, so building the whole
command line, and --help, needs no ROS. ``arguments`` holds the argument types and groups the
commands share.
"""

PROG = 'stealth'
