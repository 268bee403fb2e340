"""Real robot data in and out (``pip install 'echogym[robotdata]'``; docs/data.md).

In: :func:`import_logs` reads ROS 2 bags (sqlite3 or MCAP storage), bare MCAP files and
CSV logs into an ``echogym-recordings/1`` dataset for ``echogym calibrate``, with the
transforms a real log needs (sensor frame → world, gravity compensation, one clock,
resampling, gaps, sites). Out: :func:`export_episodes` writes episodes recorded by
:class:`RecordEpisodes` (or an env's ``record``)
as a LeRobot dataset or as a ROS 2 bag / MCAP file that Foxglove opens."""

from echogym.robotdata.errors import *  # noqa: F403 (the error tree, listed in errors.__all__)
from echogym.robotdata import errors
from echogym.robotdata.importer import ImportResult, import_logs
from echogym.robotdata.options import CsvColumns, ImportOptions, load_mapping
from echogym.robotdata.recorder import RecordEpisodes, RecordVectorEpisodes
from echogym.robotdata.episodes import Episode, read_episodes
from echogym.robotdata.export import FORMATS, export_episodes

__all__ = ["FORMATS", "CsvColumns", "Episode", "ImportOptions", "ImportResult", "RecordEpisodes",
           "RecordVectorEpisodes", "export_episodes", "import_logs", "load_mapping",
           "read_episodes", *errors.__all__]
