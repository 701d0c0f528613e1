// Opening a closed MCAP file with @mcap/core's indexed reader (footer, summary, chunk and
// message indexes), zstd and lz4 chunks included: shared by the Node.js checks of our files.
import { open } from "node:fs/promises";
import { McapIndexedReader } from "@mcap/core";
import { decompress as zstdDecompress } from "fzstd";
import { decompress as lz4Decompress } from "lz4js";

// MCAP "zstd" is a zstd frame, "lz4" an LZ4 frame (not a raw block).
export const decompressHandlers = {
  zstd: (buffer, decompressedSize) => zstdDecompress(buffer, new Uint8Array(Number(decompressedSize))),
  lz4: (buffer, decompressedSize) => lz4Decompress(buffer, Number(decompressedSize)),
};

/// Calls use(reader) with the file's McapIndexedReader and closes the file after.
export async function withIndexedReader(file, use) {
  const handle = await open(file, "r");
  try {
    const { size } = await handle.stat();
    const readable = {
      size: async () => BigInt(size),
      read: async (offset, length) => {
        const buffer = new Uint8Array(Number(length));
        for (let done = 0; done < buffer.length; ) {
          const { bytesRead } = await handle.read(buffer, done, buffer.length - done, Number(offset) + done);
          if (bytesRead === 0) throw new Error(`short read at byte ${Number(offset) + done}`);
          done += bytesRead;
        }
        return buffer;
      },
    };
    return await use(await McapIndexedReader.Initialize({ readable, decompressHandlers }));
  } finally {
    await handle.close();
  }
}
