"""The MQTT transport under the VDA 5050 fleet interface: an embedded broker and a robust client.

`broker` starts an amqtt broker on 127.0.0.1 when no real broker (mosquitto etc.) is given, and
chooses between the two (`broker_url`); `client` is the one MQTT connection of each truck's
bridge, with a last will and automatic reconnection. Neither knows ROS or VDA 5050 messages.
"""
