"""Why an MQTT connection attempt failed, as one line for a log, an exception or /diagnostics."""

import re
import ssl

READ_FAILED = 'failed to receive on socket: '  # paho's log line for a failed read


def failure_text(error: BaseException) -> str:
    """Return one line on why a connection failed (an SSL error's reason, not its errno)."""
    if isinstance(error, ssl.SSLCertVerificationError):
        return f'TLS: the broker certificate is not trusted ({error.verify_message})'
    if isinstance(error, ssl.SSLError):
        return f'TLS: {error.reason or error}'
    return str(error) or type(error).__name__


def log_failure_text(text: str) -> str:
    """Return paho's `failed to receive on socket: [SSL: X] reason (_ssl.c:N)` as `TLS: reason`."""
    text = text.removeprefix(READ_FAILED)
    match = re.fullmatch(r'\[SSL(?:: \w+)?\] (.*?)(?: \(_ssl\.c:\d+\))?', text)
    return f'TLS: {match.group(1)}' if match else text
