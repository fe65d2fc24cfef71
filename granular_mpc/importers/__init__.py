"""Import the logs labs keep — ROS 2 bags (rosbag2 sqlite3 or MCAP) and CSV / Parquet
files — into checked data sets (format v1 with declared ``channels``).

``import_log(source, mapping_file, out_dir)`` reads the streams named by a small YAML
mapping file (:class:`ImportMapping`: topic / column → channel, unit scale, quaternion
order, force-sensor frame, joint-name map, time offsets between streams), puts them on one
clock at one rate, and writes the data set with the loader's checks. Reading bags needs
the optional ``rosbags`` package (``pip install 'granular_mpc[import]'``); CSV and Parquet
need nothing more. Reference: ``docs/import.md``.

Modules, one job each: :mod:`.mapping` (the mapping file), :mod:`.sources` (reading bags
and files), :mod:`.align` (common clock, resampling), :mod:`.frames` (foot-frame forces to
the world), :mod:`.importer` (the pipeline).
"""

from .align import Aligned, align
from .importer import ImportResult, import_log
from .mapping import ChannelMap, ImportMapping, StreamMap, load_mapping
from .sources import Stream

__all__ = ["import_log", "ImportResult", "ImportMapping", "StreamMap", "ChannelMap",
           "load_mapping", "Stream", "Aligned", "align"]
