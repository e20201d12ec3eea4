// Runs the Khronos glTF-Validator on one .glb or .gltf file and prints a summary of its report
// as one JSON object on stdout:
//   {"uri", "validatorVersion", "numErrors", "numWarnings", "numInfos", "numHints",
//    "truncated", "messages": [{"code", "severity", "message", "pointer"?, "offset"?}]}
// severity: 0 error, 1 warning, 2 info, 3 hint (the validator's own numbering).
//
// Exit status 0 whenever the validator ran, whatever it found: the caller judges the counts.
// Non-zero (with the reason on stderr) only when it could not run: bad arguments, an unreadable
// file, or input the validator cannot even recognise as glTF or GLB.
//
// External resources (buffers and images next to a .gltf) are read relative to the input file.
//
// Usage: node ci/gltf-validator/validate.mjs FILE   (after `npm ci --prefix ci/gltf-validator`)

import { readFile } from "node:fs/promises";
import path from "node:path";
import * as validator from "gltf-validator";

const MAX_ISSUES = 200;

async function main(args) {
    if (args.length !== 1) {
        throw new Error("usage: node validate.mjs FILE.glb|FILE.gltf");
    }
    const file = path.resolve(args[0]);
    const bytes = new Uint8Array(await readFile(file));
    const report = await validator.validateBytes(bytes, {
        uri: path.basename(file),
        maxIssues: MAX_ISSUES,
        writeTimestamp: false,
        externalResourceFunction: async (uri) =>
            new Uint8Array(await readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)))),
    });
    const issues = report.issues;
    return {
        uri: report.uri,
        validatorVersion: report.validatorVersion,
        numErrors: issues.numErrors,
        numWarnings: issues.numWarnings,
        numInfos: issues.numInfos,
        numHints: issues.numHints,
        truncated: issues.truncated,
        messages: issues.messages,
    };
}

try {
    console.log(JSON.stringify(await main(process.argv.slice(2))));
} catch (error) {
    // The validator rejects with a plain string; everything else is an Error.
    console.error(`validate.mjs: ${error instanceof Error ? error.message : error}`);
    process.exit(2);
}
