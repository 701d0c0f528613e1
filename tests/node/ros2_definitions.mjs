// The ROS 2 interface package's message definitions (tools/ros2_package: build/ros2/pmlsm_msgs),
// read as ROS 2 tools read them: a message's text followed by every package message it uses, in
// the order first met, as rosbag2 stores a definition and as a ROS 2 node is given one.

import { readFile, readdir } from "node:fs/promises";
import { join } from "node:path";

export const PACKAGE = "pmlsm_msgs";
const SEPARATOR = "=".repeat(80);

// The file's text without the generated header (its first comment lines): what a definition holds.
export function body(text) {
  const lines = text.split("\n");
  while (lines.length > 0 && lines[0].startsWith("#")) lines.shift();
  return lines.join("\n");
}

// The package messages a definition uses, in the order first met, each once (breadth first).
export function definitionOf(name, texts) {
  const order = [name];
  for (let i = 0; i < order.length; ++i) {
    for (const line of texts.get(order[i]).split("\n")) {
      const [type_text, rest] = line.split(" ", 2);
      if (rest === undefined || rest.includes("=")) continue; // blank, or a constant "uint8 NAME=1"
      const type = type_text.split(/[[<]/)[0];
      if (texts.has(type) && !order.includes(type)) order.push(type);
    }
  }
  let text = texts.get(name);
  for (const dependency of order.slice(1)) text += `${SEPARATOR}\nMSG: ${PACKAGE}/${dependency}\n${texts.get(dependency)}`;
  return text;
}

// The package's msg/*.msg file names, sorted, and their texts by message name.
export async function readPackageTexts(dir) {
  const files = (await readdir(join(dir, "msg"))).filter((f) => f.endsWith(".msg")).sort();
  const texts = new Map();
  for (const file of files) texts.set(file.slice(0, -4), body(await readFile(join(dir, "msg", file), "utf8")));
  return { files, texts };
}
