"""Evaluation harness: scenarios through the alignment pipeline, against their truth.

ROS-free (no rclpy): the benchmarks in ``bench/`` and the tests use it.

- :mod:`.scenarios`: a named scenario (optionally with another IMU grade) and its
  whole-run simulation;
- :mod:`.cache`: the simulation cache on disk (one simulation per scenario and seed,
  shared by the runs and processes of a benchmark);
- :mod:`.feed`: whole arrays of increments and GNSS epochs through an alignment session
  in time order (:func:`~.feed.feed_arrays`);
- :mod:`.run`: one data set through an :class:`~sins_align_ros.align.session.AlignmentSession`
  (:func:`~.run.run_pipeline`, :func:`~.run.run_scenario`): the output with the truth
  at its rows and the final errors; replay speed;
- :mod:`.errors`: errors against truth (attitude, final error and NEES, navigation RMSE);
- :mod:`.stats`: statistics over runs (mean, RMS, mean reported sigma, share inside
  3 sigma, mean NEES);
- :mod:`.pool`: Monte Carlo runs over a process pool, with progress on stderr;
- :mod:`.recordings`: the real recordings of ``../shared/data`` through the pipeline;
- :mod:`.pyins_sim`: an independent IMU simulator (pyins, a test/bench-only
  dependency imported only when called) for cross-checks;
- :mod:`.evidence` and :mod:`.report`: the evidence report (every fine filter on
  every scenario against truth and the analytic limits; ``bench/report.py``);
- :mod:`.markdown`: the benchmarks' result pages.
"""
from .pool import monte_carlo
from .run import Run, replay_rate, run_pipeline, run_scenario
from .scenarios import named, simulate

__all__ = ['Run', 'monte_carlo', 'named', 'replay_rate', 'run_pipeline', 'run_scenario',
           'simulate']
