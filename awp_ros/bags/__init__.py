"""
rosbag2 files (mcap, sqlite3) with the rosbags library, and offline replay.

- :mod:`message_types`: message types and the typestore (ROS 2 Jazzy plus awp_ros_msgs).
- :mod:`reader`: BagMessage, read_bag, bag_info.
- :mod:`writer`: BagWriter.
- :mod:`player`: play a bag onto DDS at the recorded pace.
- :mod:`replay`: a bag through the pipeline into a new bag.
- :mod:`summary`: counts and margin statistics of reports.
- :mod:`progress`: the text progress bar.
"""

__all__ = ['message_types', 'reader', 'writer', 'player', 'replay', 'summary', 'progress']
