"""``python -m awp_ros.soak``: the soak test of awp_node (:mod:`awp_ros.soak.soak`)."""

import sys

from awp_ros.soak.soak import main

sys.exit(main())
