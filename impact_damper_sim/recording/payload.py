"""Payload checks for republishing a log: an undecodable message is skipped with a warning.

A player publishes recorded CDR bytes as they are; a damaged or mistyped payload would reach
every subscriber, which fails on it or reads garbage. :class:`PayloadCheck` decodes each
payload with the channel's message class before it is published and says, once per topic
and then in a summary, how many it skipped and why. Nothing here imports rclpy: the decoder
is passed in (``rclpy.serialization.deserialize_message`` in the replay node).

Typical use in a player::

    check = PayloadCheck(deserialize_message, warn=node.get_logger().warning)
    for channel_id, topic, msg_class, data in source:
        if check.ok(topic, msg_class, data):
            publisher.publish(data)
    check.summary()        # one warning per topic with skipped messages
"""
from __future__ import annotations

__all__ = ['PayloadCheck']


class PayloadCheck:
    """Decode-before-publish check with per-topic warnings.

    Parameters
    ----------
    decode : callable
        ``decode(data: bytes, msg_class) -> message``; raises on a payload it cannot read.
    warn : callable, optional
        Receives each warning line (str); default: collected in :attr:`warnings` only.

    Attributes
    ----------
    skipped : dict of str to int
        Payloads skipped per topic.
    warnings : list of str
        Every warning issued, in order.
    """

    def __init__(self, decode, warn=None):
        self._decode = decode
        self._warn = warn
        self.skipped = {}
        self.warnings = []

    def _emit(self, text):
        self.warnings.append(text)
        if self._warn is not None:
            self._warn(text)

    def ok(self, topic, msg_class, data, log_time_ns=None):
        """Return True if ``data`` decodes as ``msg_class``; warn on the topic's first failure.

        Parameters
        ----------
        topic : str
            Recorded topic name.
        msg_class : type
            Message class of the channel.
        data : bytes
            The CDR payload.
        log_time_ns : int, optional
            Its log time (ns), for the message.
        """
        try:
            self._decode(bytes(data), msg_class)
            return True
        except Exception as exc:   # any decoder failure means: do not publish it
            count = self.skipped.get(topic, 0) + 1
            self.skipped[topic] = count
            if count == 1:
                when = f' at log time {log_time_ns} ns' if log_time_ns is not None else ''
                reason = str(exc).strip().splitlines()[0][:160] if str(exc).strip() else \
                    type(exc).__name__
                self._emit(f'{topic}: skipping a payload that does not decode as '
                           f'{_name(msg_class)}{when} ({len(data)} bytes: {reason}); '
                           'further ones on this topic are counted')
            return False

    def summary(self):
        """Warn once per topic with skipped payloads; return the total skipped (int)."""
        for topic, count in sorted(self.skipped.items()):
            self._emit(f'{topic}: skipped {count} undecodable payload(s)')
        return sum(self.skipped.values())


def _name(msg_class):
    module = getattr(msg_class, '__module__', '') or ''
    pkg = module.split('.')[0]
    return f'{pkg}/msg/{msg_class.__name__}' if pkg else getattr(msg_class, '__name__', '?')
