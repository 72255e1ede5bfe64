"""The HTML report (``write_report`` in ``html``).

``inputs`` finds and reads what a folder holds (strictly: damaged files and sample ids leading out
of a dataset are refused); ``summary`` computes per-method, per-bend and per-axis statistics with
pandas group-bys; ``dataset``, ``experiment`` and ``interim`` (study and sensing sections until
``sensing`` lands) build each section as plain data; ``plots`` draws the figures, each method in its
one colour of ``colours`` (which the benchmark's leaderboard uses too), ``thumbs`` the image
thumbnails; ``page`` holds what the builders share; the page itself comes from the Jinja2
templates in ``templates/``.
"""
