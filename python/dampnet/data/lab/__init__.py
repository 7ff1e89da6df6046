"""Lab files read through their own libraries: LabVIEW TDMS (nptdms), ASAM MDF 3/4 (asammdf), MTS RPC III (rpc3-file).

  raw.py         RawChannel / RawFile: a file's channels as its library gives them (name, group,
                 unit, samples, time base), and `read_raw` picking the reader by extension
  tdms.py        TDMS: groups and channels, unit_string, wf_increment / wf_start_offset
  mdf.py         MDF 3.x / 4.x: channel groups, each with its own master time channel
  rpc.py         RPC III (drive and response files): channels sharing DELTA_T
  channelmap.py  the channel map (dampnet-channels.toml beside the data, or options)
  assemble.py    raw channels + channel map -> a checked DynoTest in SI units (resampling
                 channel groups of different rates onto one time base)

The libraries are the optional extra `lab` (pip install 'dampnet[lab]'), imported only when a
file of theirs is read; each runs in a child process (dampnet.data.child).
"""

from dampnet.data.lab.assemble import read_lab_file, read_lab_folder
from dampnet.data.lab.channelmap import MAP_FILE, ChannelMap, load_channel_map
from dampnet.data.lab.raw import LAB_SUFFIXES, is_lab_file

__all__ = ["read_lab_file", "read_lab_folder", "MAP_FILE", "ChannelMap", "load_channel_map",
           "LAB_SUFFIXES", "is_lab_file"]
