"""Reader for MCAP recordings: ROS 1 (``ros1msg``), ROS 2 (``cdr``) and gridmap's JSON channels.

The file is streamed in log-time order through the ``mcap`` library's indexed reader, decoding
only the topics the plan (:func:`~gridmap_cli.readers.ros.topics.plan_topics`) chose; the
messages become the canonical stream as for every ROS container
(:mod:`~gridmap_cli.readers.ros.messages`). ``docs/reading-ros.md`` states the rules for users.
"""

from __future__ import annotations

import contextlib
import io
import json
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.records import Channel, Schema
from mcap.records import Message as McapMessage

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.mcap.bulk import Batch, bulk_enabled, indexed_messages, read_bulk
from gridmap_cli.readers.ros.mcap.channels import (
    DAMAGED,
    message_type,
    open_reader,
    read_summary,
    survey_mcap,
)
from gridmap_cli.readers.ros.mcap.channels import sniff as sniff
from gridmap_cli.readers.ros.mcap.integrity import summary_intact, verify_mcap
from gridmap_cli.readers.ros.messages import float32_decimal as float32_decimal
from gridmap_cli.readers.ros.recording import Message, RecordingRead, read_recording
from gridmap_cli.readers.ros.topics import Survey
from gridmap_cli.records import RangeLog


class JsonDecoderFactory(McapDecoderFactory):
    """Decodes channels with message encoding ``json`` into plain dicts."""

    def decoder_for(self, message_encoding: str, schema: Schema | None) -> Any:
        if message_encoding != "json":
            return None
        return lambda data: json.loads(data)


class McapSource:
    """An MCAP file as a recording source.

    The whole file's structure and CRCs are checked (:func:`verify_mcap`) before any message
    is used, once per source: the ``mcap`` library trusts both. The survey reads only the
    summary, so only the summary's CRC is checked before it (any damage found there is named
    by the whole check); the bulk read then checks every chunk as it decompresses it, once for
    both.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self._verified = False

    def verify(self, take_chunk: Callable[[int, bytes], None] | None = None) -> None:
        """Check the whole file (once), handing ``take_chunk`` each chunk's offset and its
        checked, decompressed records."""
        if not self._verified:
            verify_mcap(self.path, take_chunk)
            self._verified = True

    def survey(self) -> Survey:
        if not self._verified and not summary_intact(self.path):
            self.verify()
        try:
            return survey_mcap(self.path)
        except InputFileError:
            self.verify()  # damage anywhere is named first, where the check finds it
            raise

    def bulk(self, topics: Sequence[str]) -> tuple[list[Batch], list[str]]:
        """The topics whose messages can be decoded in bulk (:mod:`~gridmap_cli.readers.
        mcap_bulk`), decoded; and the topics left for :meth:`messages`."""
        path = self.path
        decoder_for = library_decoders(path)
        walk = None if self._verified else self.verify
        try:
            with open(path, "rb") as handle:
                reader = open_reader(path, handle)
                summary = read_summary(path, reader)
                return read_bulk(path, handle, summary, topics, decoder_for, walk)
        except InputFileError:
            raise
        except DAMAGED as exc:
            raise damage_error(path, exc) from exc

    def messages(self, topics: Sequence[str], every_topic: bool) -> Iterator[Message]:
        self.verify()
        if not topics and not every_topic:
            return  # every topic read in bulk: nothing to walk the chunks for
        path = self.path
        wanted = set(topics)
        decoder_for = library_decoders(path)
        seen: Counter[str] = Counter()  # messages of each topic so far: names a bad one
        name = str(path)
        try:
            with open(path, "rb") as handle:
                reader = open_reader(path, handle)
                summary = read_summary(path, reader)
                # the few messages of topics not read in bulk: through the indexes
                found: Iterable[tuple[Schema | None, Channel, McapMessage]] | None = None
                if not every_topic and bulk_enabled():
                    found = indexed_messages(path, handle, summary, topics)
                if found is None:
                    found = reader.iter_messages(
                        topics=None if every_topic else list(topics), log_time_order=True
                    )
                for schema, channel, message in found:
                    seen[channel.topic] += 1
                    index = seen[channel.topic]
                    type_name = message_type(schema)
                    if channel.topic not in wanted:
                        yield name, channel.topic, type_name, message.log_time, None
                        continue
                    decoder = decoder_for(channel, schema)
                    decoded = _decode(path, decoder, channel, type_name, index, message.log_time,
                                      message.data)  # fmt: skip
                    yield name, channel.topic, type_name, message.log_time, decoded
        except InputFileError:
            raise
        except DAMAGED as exc:
            raise damage_error(path, exc) from exc


def read_mcap_log(source: str | Path, options: ReadOptions | None = None) -> RangeLog:
    """Read an MCAP recording into the canonical record stream.

    Raises :class:`InputFileError` naming the file (and topic) for damaged files, missing
    odometry or ranges, unknown sensor mounting; :class:`UsageError` for a topic flag that
    names no usable topic.
    """
    return read_mcap(source, options).log


def read_mcap(
    source: str | Path,
    options: ReadOptions | None = None,
    strict: bool = True,
    every_topic: bool = False,
) -> RecordingRead:
    """:func:`read_mcap_log`, also returning what was chosen (for ``inspect``); see
    :func:`~gridmap_cli.readers.ros.recording.read_recording`."""
    return read_recording([McapSource(Path(source))], options, strict, every_topic)


def damage_error(path: Path, exc: BaseException) -> InputFileError:
    """The one-line error for what the mcap library raised reading ``path`` (:data:`DAMAGED`)."""
    if isinstance(exc, OSError) and not isinstance(exc, EOFError):
        return InputFileError(path, f"cannot read: {exc.strerror or exc}")
    return InputFileError(path, f"truncated or damaged MCAP data ({type(exc).__name__}: {exc})")


def library_decoders(path: Path) -> Callable[[Channel, Schema | None], Callable[[bytes], Any]]:
    """A channel's library decoder (ROS 1, ROS 2 or JSON), made once per channel."""
    decoders: dict[int, Callable[[bytes], Any]] = {}

    def decoder_for(channel: Channel, schema: Schema | None) -> Callable[[bytes], Any]:
        if channel.id not in decoders:
            factories = _factories(channel.message_encoding)
            decoders[channel.id] = _decoder(path, factories, channel, schema)
        return decoders[channel.id]

    return decoder_for


def _factories(encoding: str | None = None) -> list[McapDecoderFactory]:
    """The decoder factories, or only the one for a channel's ``encoding`` (a JSON recording
    then loads no ROS decoder, a ROS 2 one no ROS 1 decoder)."""
    if encoding == "json":
        return [JsonDecoderFactory()]
    if encoding == "ros1":
        from mcap_ros1.decoder import DecoderFactory as Ros1DecoderFactory

        return [Ros1DecoderFactory()]
    if encoding == "cdr":
        from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

        return [Ros2DecoderFactory()]
    from mcap_ros1.decoder import DecoderFactory as Ros1DecoderFactory
    from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

    return [Ros1DecoderFactory(), Ros2DecoderFactory(), JsonDecoderFactory()]


def _decoder(
    path: Path, factories: list[McapDecoderFactory], channel: Channel, schema: Schema | None
) -> Callable[[bytes], Any]:
    """The decoder of a channel's messages: ROS 1, ROS 2 (CDR) or JSON.

    A schema that does not parse is the file's fault: :class:`InputFileError` naming the topic.
    """
    for factory in factories:
        try:
            # the ROS 2 parser prints its own note on stderr before raising: the error below
            # says it on gridmap's one line
            with contextlib.redirect_stderr(io.StringIO()):
                decoder = factory.decoder_for(channel.message_encoding, schema)
        except Exception as exc:  # the vendored ROS parsers raise a dozen classes of their own
            raise InputFileError(
                path,
                f"{channel.topic}: the schema of {message_type(schema) or 'its type'} does not "
                f"parse ({type(exc).__name__}: {_short(exc)})",
            ) from exc
        if decoder is not None:
            return decoder
    raise InputFileError(
        path,
        f"{channel.topic}: cannot decode {channel.message_encoding} messages of "
        f"{message_type(schema) or 'no schema'}",
    )


def _decode(
    path: Path,
    decoder: Callable[[bytes], Any],
    channel: Channel,
    type_name: str,
    index: int,
    log_time: int,
    data: bytes,
) -> Any:
    """One message decoded; any failure (a length claiming more bytes than the message holds,
    JSON nested past the interpreter's recursion limit) names the message by its place among
    its topic's messages in log-time order (whatever other topics were read with it)."""
    try:
        return decoder(data)
    except Exception as exc:  # RecursionError, genpy/CDR/JSON errors: all mean a bad message
        raise InputFileError(
            path,
            f"message {index} of {channel.topic} ({type_name or 'no schema'}, log time "
            f"{log_time / 1e9:.9f} s) does not decode ({type(exc).__name__}: {_short(exc)})",
        ) from exc


def _short(exc: BaseException, limit: int = 200) -> str:
    """An exception's text on one line, cut to ``limit`` characters."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."
