"""The MQTT transport under the VDA 5050 fleet interface: the local broker and a robust client.

`broker` chooses the broker (`broker_url`: the one named, else a local one the launcher starts:
`mosquitto`, or the embedded amqtt where mosquitto is not installed); `address` reads mqtt[s]://
URLs and holds a link's TLS files and credentials; `client` is the one MQTT connection of each
truck's bridge, with a last will, automatic reconnection, TLS and a password. None of them
knows ROS or VDA 5050 messages.
"""
