"""A converged stand-in for the real world: the gap benchmark's push logs, on a code path of its own.

The sim-to-real diagnostic (:mod:`imply.diagnose`) reads the push table and effect
tables built by :mod:`imply.sim.pushes`. A benchmark that made its "real" pushes the
same way would share the diagnostic's numerical mistakes. Its worlds do not import
:mod:`imply.diagnose`, read no table and interpolate nothing (only the modules that score
the diagnoses read them: :mod:`~imply.realworld.benchmark`,
:mod:`~imply.realworld.benchmark_report` and :mod:`~imply.realworld.closed_loop`):

- :mod:`~imply.realworld.world` steps the push scene with MuJoCo's ``RK4`` integrator on
  uniform steps (no shortened slide steps, no travel correction: the table's
  semi-implicit Euler stepping is not used), and injects every effect through its own
  mechanism: a tilted table rotates gravity in full, viscous friction and air drag are
  applied forces, anisotropic, speed-dependent (Stribeck) and position-dependent
  friction are friction laws evaluated at every step;
- :mod:`~imply.realworld.effects` lists the effects the world can carry, those the
  diagnostic has candidates for and those it has not;
- :mod:`~imply.realworld.contact` gives the world a contact model of its own (a table
  contact of another stiffness and damping, speed-dependent or regularised friction, another
  pusher-box contact) or another physics engine's, for the contact benchmark;
- :mod:`~imply.realworld.cases` draws the benchmark's logs (objects, magnitudes,
  azimuths, noise, outliers, what was measured; in the contact benchmark also the
  engine, the contact model and the push design) and writes each log and, apart, its
  sealed label;
- :mod:`~imply.realworld.bullet` simulates the same pushes in a second physics engine
  (Bullet), for logs whose contact model is not MuJoCo's;
- :mod:`~imply.realworld.sapien_world` simulates them in a third engine (PhysX, through
  SAPIEN), on the rig protocol :mod:`~imply.realworld.stepped` shares with Bullet;
- :mod:`~imply.realworld.probes` runs the calibration probes a lab would (free strokes,
  pull tests of friction, pushes with an added mass) in any of these worlds;
- :mod:`~imply.realworld.lab` draws and writes the lab benchmark's development and sealed
  sets, and :mod:`~imply.realworld.separability` marks each of their effect logs separable or
  not from its contact;
- :mod:`~imply.realworld.accuracy` measures the world's own numerical error against a
  much finer run of itself and against :mod:`imply.sim.reference`.
"""
