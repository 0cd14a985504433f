// Read MCAP files with a second implementation (TypeScript @mcap/core) and print, per file, one
// JSON line: header, message counts per topic from the indexed reader, from the streaming
// reader, and from the summary statistics. CRCs are validated by both readers. Exit 1 (with the
// reason on stderr) when a file cannot be read, or when the three counts disagree, or when the
// indexed reader yields messages out of log-time order.
//
// usage: node validate_mcap.mjs FILE.mcap [FILE.mcap ...]

import { open, readFile } from "node:fs/promises";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { decompress } from "fzstd";

const decompressHandlers = {
  zstd: (buffer, decompressedSize) =>
    decompress(buffer, new Uint8Array(Number(decompressedSize))),
};

function fileReadable(handle, size) {
  return {
    size: async () => BigInt(size),
    read: async (offset, length) => {
      const out = new Uint8Array(Number(length));
      await handle.read(out, 0, out.length, Number(offset));
      return out;
    },
  };
}

function increment(counts, topic) {
  counts[topic] = (counts[topic] ?? 0) + 1;
}

async function indexedCounts(path) {
  const handle = await open(path, "r");
  try {
    const { size } = await handle.stat();
    const reader = await McapIndexedReader.Initialize({
      readable: fileReadable(handle, size),
      decompressHandlers,
    });
    const counts = {};
    let last = -1n;
    for await (const message of reader.readMessages({ validateCrcs: true })) {
      if (message.logTime < last) {
        throw new Error(`message at ${message.logTime} ns after one at ${last} ns`);
      }
      last = message.logTime;
      increment(counts, reader.channelsById.get(message.channelId).topic);
    }
    const statistics = {};
    for (const [channelId, count] of reader.statistics?.channelMessageCounts ?? []) {
      statistics[reader.channelsById.get(channelId).topic] = Number(count);
    }
    const metadata = [];
    for await (const record of reader.readMetadata()) {
      metadata.push(record.name);
    }
    return { header: reader.header, counts, statistics, metadata };
  } finally {
    await handle.close();
  }
}

async function streamedCounts(path) {
  const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  reader.append(await readFile(path));
  const topics = new Map();
  const counts = {};
  let footer = false;
  for (let record; (record = reader.nextRecord()); ) {
    if (record.type === "Channel") {
      topics.set(record.id, record.topic);
    } else if (record.type === "Message") {
      increment(counts, topics.get(record.channelId));
    } else if (record.type === "Footer") {
      footer = true;
    }
  }
  if (!footer || !reader.done()) {
    throw new Error("the stream ended before the footer and closing magic");
  }
  return counts;
}

function sameCounts(a, b) {
  const keys = Object.keys(a).sort();
  return (
    JSON.stringify(keys) === JSON.stringify(Object.keys(b).sort()) &&
    keys.every((k) => a[k] === b[k])
  );
}

let failed = false;
for (const path of process.argv.slice(2)) {
  try {
    const indexed = await indexedCounts(path);
    const streamed = await streamedCounts(path);
    if (!sameCounts(indexed.counts, streamed) || !sameCounts(indexed.counts, indexed.statistics)) {
      throw new Error(
        `counts disagree: indexed ${JSON.stringify(indexed.counts)}, streamed ` +
          `${JSON.stringify(streamed)}, statistics ${JSON.stringify(indexed.statistics)}`,
      );
    }
    console.log(
      JSON.stringify({
        file: path,
        profile: indexed.header.profile,
        library: indexed.header.library,
        counts: indexed.counts,
        metadata: indexed.metadata,
      }),
    );
  } catch (error) {
    console.error(`${path}: ${error.message}`);
    failed = true;
  }
}
process.exit(failed ? 1 : 0);
