"""The project's colours, each named for what it shows, so that the scenario pictures, the
RViz/Foxglove markers, the Gymnasium frames and the plots of runs and experiments show one thing
in one colour.

Three forms, as each drawer takes them: matplotlib colours for the pictures (stealth_core.render,
scenario_drawing) and plots (stealth_bringup.run_outputs, stealth_experiments.harness_report),
RGBA in [0, 1] for the markers (stealth_env.markers: the pictures' colours rounded to 3
decimals, with the alpha the scene needs) and 0-255 RGB for the frames of gym_env's rgb_array
render.
"""

# --- the scenario pictures (matplotlib colours) -------------------------------------------------

HEATMAP = 'YlOrRd'  # the colour map of total visibility on free cells
WALL = (0.08, 0.08, 0.1, 1.0)  # occupied cells
UNKNOWN_SPACE = (0.62, 0.62, 0.65, 1.0)  # unknown cells (they block light)
DARK_FLOOR = '#f4f6fb'  # free cells no light reaches
LIGHT = '#1f4e9e'  # searchlight cones, sweeps, patrol routes and names
LAMP = '#ffd92f'  # the star at each lamp
LAMP_EDGE = 'black'
DETECTION = '#b2182b'  # the detection threshold: its contour and its line on the colour bar
START = '#1a9641'
GOAL = '#7b3294'
MARK_EDGE = 'white'  # the edge of the start and goal marks
LABEL_BACKGROUND = 'white'  # behind the names of lights, goals and the start
PATHS = ('#0571b0', '#d01c8b', '#018571', '#000000', '#8c510a', '#762a83')  # in turn

# --- the RViz/Foxglove markers (RGBA in [0, 1]) ------------------------------------------------

# HEATMAP at 0, 0.25, ... 1: the cone's colour by the light's intensity, as the pictures.
MARKER_HEATMAP_STOPS = (
    (1.000, 1.000, 0.800),
    (0.996, 0.851, 0.463),
    (0.992, 0.553, 0.235),
    (0.890, 0.102, 0.110),
    (0.502, 0.000, 0.149),
)
MARKER_LIGHT = (0.122, 0.306, 0.620, 0.9)  # LIGHT: the cones' outlines
MARKER_MOTION = (*MARKER_LIGHT[:3], 0.4)  # a sweep's sector, a patrol's route
MARKER_DETECTION = (0.890, 0.102, 0.110, 0.9)  # where one light reaches the threshold
MARKER_LAMP = (1.0, 0.851, 0.184, 1.0)  # LAMP
MARKER_START = (0.102, 0.588, 0.255, 0.8)  # START
MARKER_GOAL = (0.482, 0.196, 0.580, 0.7)  # GOAL: the goal pursued
MARKER_OTHER_GOAL_ALPHA = 0.25  # the other goals: MARKER_GOAL, fainter
MARKER_TEXT = (1.0, 1.0, 1.0, 1.0)  # names and labels

# --- the Gymnasium environment's rgb_array frames (0-255 RGB) -----------------------------------

FRAME_PATH = (5, 113, 176)  # PATHS[0]: the path walked
FRAME_ROBOT = (26, 150, 65)  # START
FRAME_GOAL = (123, 50, 148)  # GOAL

# --- the plots of runs and experiments (matplotlib colours) -------------------------------------

OUTCOMES = {  # by stealth_core.reward.EpisodeOutcome name: an episode's bar in the learning curve
    'SUCCESS': START,
    'DETECTED': '#d7191c',
    'TIMEOUT': '#fdae61',
    'ABORTED': '#7f7f7f',
}
UNKNOWN_OUTCOME = OUTCOMES['ABORTED']
RETURN = '#253494'  # the moving average of the return, and the optimum's return
STREAK = START  # where the greedy success streak that ended the run began
PLOT_INK = 'black'  # edges, epsilon, and the optimum of the experiments' plots
PLOT_PAPER = 'white'  # the fill of the greedy-evaluation legend mark
LEARNERS = {'qlearning': PATHS[0], 'sarsa': PATHS[1], 'dyna': PATHS[2], 'prioritized': PATHS[4]}
TRACKS = {'full': PATHS[0], 'sensed': PATHS[1]}  # the benchmark's bars of each track
