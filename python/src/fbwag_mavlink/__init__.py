"""The FBWAG MAVLink dialect for pymavlink, and the MAVProxy module `fbwag`.

Installing the distribution fbwag-mavlink places:
  pymavlink/dialects/v20/fbwag.py   pymavlink 2.4.50's mavgen output for
                                    message_definitions/fbwag.xml, wire 2.0
  pymavlink/dialects/v10/fbwag.py   the same, wire 1.0 (no FBWAG_NOTICE: ids
                                    above 255 do not exist in MAVLink 1)
  MAVProxy/modules/mavproxy_fbwag.py  `module load fbwag` in MAVProxy
  fbwag_mavlink/                    this package: the module's code
                                    (mavproxy_fbwag) and its MAVProxy-free
                                    core (monitor)

so that `mavutil.mavlink_connection(..., dialect="fbwag")`,
`mavproxy.py --dialect=fbwag` and `module load fbwag` find them.
"""
__version__ = "0.1.0"

#: FBWAG_NOTICE's message id and CRC_EXTRA (fixed by the paper's definition).
FBWAG_NOTICE_ID = 15001
FBWAG_NOTICE_CRC_EXTRA = 30


def dialect(wire="2.0"):
    """The installed pymavlink bindings of the FBWAG dialect for a wire
    protocol ("2.0" or "1.0")."""
    import importlib

    sub = {"2.0": "v20", "1.0": "v10"}[wire]
    return importlib.import_module("pymavlink.dialects.%s.fbwag" % sub)
