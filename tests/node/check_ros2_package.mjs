#!/usr/bin/env node
// Third-party check of the ROS 2 interface package the build makes from idl/ (tools/ros2_package):
// every msg/*.msg parsed by @foxglove/rosmsg (the parser Foxglove reads ROS 2 bags with) with the
// messages it uses, as rosbag2 stores a definition; package.xml and CMakeLists.txt name what a
// `colcon build` needs. With a recording of the ros2 profile, every ros2msg schema in it must be
// the package's definition of that message, byte for byte: a ROS 2 user's installed package and
// our recordings describe the same types.
//
//   node check_ros2_package.mjs PACKAGE_DIR [RECORDING.mcap]
//
// Prints one JSON line {"messages":N,"constants":N,"schemas_checked":N,"errors":[...]}; exits 1 on
// any error, 2 on a usage error.

import { readFile } from "node:fs/promises";
import { join } from "node:path";
import { parse } from "@foxglove/rosmsg";
import { withIndexedReader } from "./mcap_file.mjs";
import { PACKAGE, definitionOf, readPackageTexts } from "./ros2_definitions.mjs";

async function checkPackage(dir, errors) {
  const xml = await readFile(join(dir, "package.xml"), "utf8");
  for (const needed of [
    '<package format="3">',
    `<name>${PACKAGE}</name>`,
    "<buildtool_depend>rosidl_default_generators</buildtool_depend>",
    "<exec_depend>rosidl_default_runtime</exec_depend>",
    "<member_of_group>rosidl_interface_packages</member_of_group>",
  ]) {
    if (!xml.includes(needed)) errors.push(`package.xml lacks ${needed}`);
  }
  const cmake = await readFile(join(dir, "CMakeLists.txt"), "utf8");
  const { files, texts } = await readPackageTexts(dir);
  const listed = [...cmake.matchAll(/"msg\/([A-Za-z0-9]+\.msg)"/g)].map((m) => m[1]).sort();
  if (JSON.stringify(files) !== JSON.stringify(listed)) {
    errors.push(`CMakeLists.txt lists ${listed.join(", ")} but msg/ holds ${files.join(", ")}`);
  }
  let constants = 0;
  for (const [name, text] of texts) {
    try {
      const definitions = parse(definitionOf(name, texts), { ros2: true });
      const fields = definitions[0].definitions;
      const lines = text.split("\n").filter((l) => l !== "" && !l.startsWith("#"));
      if (fields.length !== lines.length) errors.push(`${name}: ${lines.length} lines parsed to ${fields.length} fields`);
      for (const field of fields) {
        if (field.isConstant) {
          ++constants;
          if (typeof field.value !== "number" && typeof field.value !== "bigint") {
            errors.push(`${name}.${field.name}: constant value ${field.value} is not a number`);
          }
        } else if (field.isComplex && !definitions.some((d) => d.name === field.type)) {
          errors.push(`${name}.${field.name}: type ${field.type} is not defined with it`);
        }
      }
    } catch (error) {
      errors.push(`${name}: @foxglove/rosmsg cannot parse it: ${error.message}`);
    }
  }
  return { texts, constants };
}

async function checkRecording(file, texts, errors) {
  return withIndexedReader(file, async (reader) => {
    if (reader.header.profile !== "ros2") errors.push(`${file}: header profile '${reader.header.profile}', not 'ros2'`);
    let checked = 0;
    for (const schema of reader.schemasById.values()) {
      const name = schema.name.replace(`${PACKAGE}/msg/`, "");
      if (schema.encoding !== "ros2msg") {
        errors.push(`schema ${schema.name}: encoding ${schema.encoding}`);
      } else if (!texts.has(name)) {
        errors.push(`schema ${schema.name}: no such message in the package`);
      } else if (new TextDecoder().decode(schema.data) !== definitionOf(name, texts)) {
        errors.push(`schema ${schema.name}: differs from the package's definition`);
      } else {
        ++checked;
      }
    }
    return checked;
  });
}

async function main() {
  const [dir, recording, ...rest] = process.argv.slice(2);
  if (dir === undefined || rest.length > 0) {
    console.error("usage: node check_ros2_package.mjs PACKAGE_DIR [RECORDING.mcap]");
    return 2;
  }
  const errors = [];
  let result = { messages: 0, constants: 0, schemas_checked: 0 };
  try {
    const { texts, constants } = await checkPackage(dir, errors);
    result = { messages: texts.size, constants, schemas_checked: 0 };
    if (recording !== undefined) result.schemas_checked = await checkRecording(recording, texts, errors);
    if (texts.size === 0) errors.push("no message in the package");
    if (recording !== undefined && result.schemas_checked === 0) errors.push("no ros2msg schema checked");
  } catch (error) {
    errors.push(error.message);
  }
  console.log(JSON.stringify({ ...result, errors }));
  return errors.length > 0 ? 1 : 0;
}

process.exitCode = await main();
