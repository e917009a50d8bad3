"""What the tests of several folders share, importable as ``harness`` (``pythonpath`` in
pyproject.toml puts ``tests/`` on the path; the product never imports it):

* :mod:`harness.plain_sixbar`: an independent six-bar solution, a plain loop over crank angles;
* :mod:`harness.report_cases`: candidate six-bars built without a database, as the query does;
* :mod:`harness.pool_faults`: work items that fail the way a pool worker can;
* :mod:`harness.processes`: the fault tests' rig — atlas builds and queries run as processes,
  killed and inspected (the fault tests and the atlas command's tests);
* :mod:`harness.dask_cluster`: a local dask cluster and what its scheduler holds (the dask
  engine's tests).
"""
