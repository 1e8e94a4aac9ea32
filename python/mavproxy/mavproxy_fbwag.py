"""MAVProxy's name for the module `fbwag` (`module load fbwag`): installed
by the fbwag-mavlink wheel as MAVProxy/modules/mavproxy_fbwag.py. The module
itself is fbwag_mavlink.mavproxy_fbwag."""
from fbwag_mavlink.mavproxy_fbwag import FbwagModule, init

__all__ = ["FbwagModule", "init"]
