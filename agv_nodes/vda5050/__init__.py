"""VDA 5050 version 2.1 messages: the wire format between a master control and our trucks.

pydantic models of the six topics (order, instantActions, state, visualization, connection,
factsheet) with the standard's field names, enumerations and value ranges, a strict parser whose
error names every offending field, and the MQTT topic names. No ROS and no MQTT in here: the
bridge that drives a truck from a master control (e.g. openTCS) builds on these.
"""

VERSION = '2.1.0'  # the protocol version our messages carry in their header (6.4)
MAJOR = 'v2'  # the majorVersion topic level (6.3)
INTERFACE = 'uagv'  # the interfaceName topic level the standard suggests for a local broker (6.3)
