"""At QoS 1 a flood loses nothing: 20,000 messages through mosquitto, each counted on arrival.

The publisher sends as fast as paho queues them (no pacing); the receiver records each sequence
number. QoS 1 promises at-least-once: every number must arrive; a duplicate would be allowed
by MQTT but, with the connection never lost, none is expected, so duplicates are counted and
must be zero too. The broker is mosquitto with the launcher's configuration
(agv_nodes.mqtt.mosquitto), whose queue per client is large enough for the flood.
"""

from __future__ import annotations

from collections import Counter
import threading
import time

import mqtt_broker
import pytest

from agv_nodes.mqtt.client import MqttLink

pytestmark = [pytest.mark.wall_clock, pytest.mark.timeout(180)]
mosquitto_url = mqtt_broker.mosquitto_url  # a private mosquitto for this module

FLOOD = 20_000  # the size of the flood the embedded amqtt broker lost messages in
TOPIC = 'uagv/v2/m/agv1/order'
# a bound only: the flood takes a few seconds on an idle 2-core machine
ARRIVAL_S = 120.0


def test_a_qos1_flood_through_mosquitto_loses_nothing(mosquitto_url):
    """20,000 QoS 1 publishes in a burst: all 20,000 sequence numbers arrive, none twice."""
    seen: Counter[int] = Counter()
    lock = threading.Condition()

    def arrived(topic: str, payload: bytes) -> None:
        with lock:
            seen[int(payload)] += 1
            lock.notify_all()

    receiver = MqttLink(mosquitto_url, 'flood_receiver')
    sender = MqttLink(mosquitto_url, 'flood_sender')
    receiver.connect(timeout=10.0)
    sender.connect(timeout=10.0)
    try:
        assert receiver.subscribe(TOPIC, 1, arrived)
        started = time.monotonic()
        assert all(sender.publish(TOPIC, str(n).encode(), qos=1) for n in range(FLOOD))
        with lock:
            lock.wait_for(lambda: len(seen) == FLOOD, ARRIVAL_S)
        took = time.monotonic() - started
        missing = sorted(set(range(FLOOD)) - set(seen))
        assert not missing, (f'{len(missing)} of {FLOOD} lost (first {missing[:10]}) after '
                             f'{took:.1f} s')
        assert set(seen) == set(range(FLOOD))
        duplicates = sum(count - 1 for count in seen.values())
        assert duplicates == 0, f'{duplicates} duplicates without a reconnect'
        stats = receiver.stats()
        assert stats.messages_in == FLOOD and stats.reconnects == 0
        assert sender.stats().messages_out == FLOOD and sender.stats().messages_dropped == 0
        print(f'{FLOOD} QoS 1 messages through mosquitto in {took:.1f} s')
    finally:
        sender.close()
        receiver.close()
