"""``python -m platebench.bench.run.plugin_process PARENT_PID``: the process plug-ins run in
(``bench.run.plugin_host``), answering the requests of ``bench.run.plugins``."""
import sys

from platebench.bench.run import plugins
from platebench.bench.run.plugin_host import serve

if __name__ == "__main__":
    serve(plugins.serve_request, int(sys.argv[1]))
