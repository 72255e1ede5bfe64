"""The fault-injection harness of PlateBench's command line: a developer tool of this repository, not
part of the installed package. ``python -m tools.faults --help`` (from the repository root) runs it;
``bad_inputs`` holds the harness and its base cases, the ``bad_inputs_*`` modules add families of
cases, ``run_attacks`` the attacks on runs, ``chaos`` the kill-and-resume test of a Dask sweep."""
