"""A plain Foxglove WebSocket client, written from the published protocol (foxglove.websocket.v1).

Nothing of foxglove-sdk: the `websockets` package speaks the WebSocket, and the protocol's
messages are read as the specification lays them out (github.com/foxglove/ws-protocol,
docs/spec.md): JSON text frames `serverInfo` and `advertise` from the server, `subscribe` from
the client, and binary frames whose first byte is the opcode (1: message data) followed by the
subscription id (uint32, little-endian), the log time (uint64, ns) and the payload. A channel's
payload is decoded by its advertised encoding: `json` as JSON, `protobuf` with the protobuf
library from the FileDescriptorSet the channel advertises (base64).
"""

from __future__ import annotations

import base64
import json
import struct
import time
from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.json_format import MessageToDict
from websockets.sync.client import connect

# The spec's subprotocol, and the name foxglove-sdk's server takes the same framing under (it
# refuses a handshake that offers only the first); the client offers both, as the app does.
SUBPROTOCOLS = ['foxglove.websocket.v1', 'foxglove.sdk.v1']
MESSAGE_DATA = 0x01


class FoxgloveClient:
    """Connects, learns the channels, subscribes and decodes what comes."""

    def __init__(self, url: str, timeout: float = 10.0) -> None:
        self.ws = connect(url, subprotocols=SUBPROTOCOLS, open_timeout=timeout)
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}  # topic -> advertised channel
        self._subs: dict[int, dict[str, Any]] = {}  # subscription id -> channel
        self._classes: dict[int, Any] = {}

    def close(self) -> None:
        """Close the connection."""
        self.ws.close()

    def _take_text(self, text: str) -> None:
        msg = json.loads(text)
        if msg.get('op') == 'serverInfo':
            self.server_info = msg
        elif msg.get('op') == 'advertise':
            for channel in msg['channels']:
                self.channels[channel['topic']] = channel
        elif msg.get('op') == 'unadvertise':
            gone = set(msg['channelIds'])
            self.channels = {t: c for t, c in self.channels.items() if c['id'] not in gone}

    def _next(self, deadline: float, missing: str) -> bytes | None:
        """Return the next binary frame, taking text frames on the way (None: none yet)."""
        left = deadline - time.monotonic()
        assert left > 0, missing
        try:
            frame = self.ws.recv(timeout=left)
        except TimeoutError:
            return None
        if isinstance(frame, str):
            self._take_text(frame)
            return None
        return frame

    def wait_for_channels(self, topics: list[str], timeout: float) -> None:
        """Read until every topic in `topics` is advertised (AssertionError on timeout)."""
        deadline = time.monotonic() + timeout
        while not set(topics) <= set(self.channels):
            self._next(deadline, f'not advertised: {sorted(set(topics) - set(self.channels))}')

    def subscribe(self, topics: list[str]) -> None:
        """Subscribe to the advertised channels of `topics`."""
        subs = []
        for topic in topics:
            channel = self.channels[topic]
            sub_id = len(self._subs) + 1
            self._subs[sub_id] = channel
            subs.append({'id': sub_id, 'channelId': channel['id']})
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))

    def first_of_each(self, topics: list[str], timeout: float,
                      want=lambda topic, msg: True) -> dict[str, Any]:
        """Return, per topic, the first decoded message `want` accepts (AssertionError if not)."""
        got: dict[str, Any] = {}
        deadline = time.monotonic() + timeout
        while set(topics) - set(got):
            frame = self._next(deadline, f'no message of {sorted(set(topics) - set(got))}')
            if frame is None or frame[0] != MESSAGE_DATA:
                continue
            sub_id, _log_time = struct.unpack_from('<IQ', frame, 1)
            channel = self._subs.get(sub_id)
            if channel is None or channel['topic'] in got:
                continue
            msg = self.decode(channel, frame[13:])
            if want(channel['topic'], msg):
                got[channel['topic']] = msg
        return got

    def decode(self, channel: dict[str, Any], payload: bytes) -> Any:
        """Decode a payload by the channel's advertised encoding."""
        if channel['encoding'] == 'json':
            return json.loads(payload)
        assert channel['encoding'] == 'protobuf', channel['encoding']
        cls = self._classes.get(channel['id'])
        if cls is None:
            files = descriptor_pb2.FileDescriptorSet.FromString(
                base64.b64decode(channel['schema']))
            pool = descriptor_pool.DescriptorPool()
            for f in files.file:
                pool.Add(f)
            cls = message_factory.GetMessageClass(
                pool.FindMessageTypeByName(channel['schemaName']))
            self._classes[channel['id']] = cls
        return MessageToDict(cls.FromString(payload), preserving_proto_field_name=True)
