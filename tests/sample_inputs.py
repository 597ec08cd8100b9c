"""Small, valid inputs shared by the tests of the commands that read them."""

# the coarse effect grid of every test that diagnoses (--effect-grid-json): one grid, so the run's shared effect-table
# cache (conftest effect_cache) builds each table once
EFFECT_GRID_JSON = (
    '{"n_speeds": 4, "n_masses": 4, "n_frictions": 4, "stop_speeds": 5, "stop_masses": 4, "stop_frictions": 4, '
    '"floor_pushes": 24}'
)

# two objects for `imply score`: a with its two calibration pushes, b without
ROLLOUTS_CSV = """object_id,role,speed,displacement
a,calibration,0.3,0.035
a,calibration,0.8,0.16
a,rollout,0.25,0.03
a,rollout,0.55,0.08
a,rollout,0.85,0.18
b,rollout,0.4,0.05
b,rollout,0.7,0.11
"""

# two objects for `imply diagnose`, one pushed in several directions
PUSHLOG_CSV = """object_id,speed,displacement,direction
a,0.3,0.05,0
a,0.5,0.09,1.57
a,0.7,0.14,3.14
b,0.3,0.04,0
b,0.5,0.07,0
b,0.7,0.10,0
"""
