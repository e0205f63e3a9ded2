// Converts the shared OBJ scenes to glTF 2.0 with tools that are not stereotrace's, for its
// glTF tests (tests/gltf_shared_scenes.rs):
//
//   node convert.mjs SHARED_SCENES OUT [SCENE...]
//
// 1. obj2gltf (Cesium) converts scene.obj + scene.mtl + textures to a GLB.
// 2. glTF-Transform rewrites what obj2gltf's Blinn-Phong conversion cannot carry, from the
//    MTL's own PBR values (obj2gltf keeps Kd, maps and names, but drops Pr/Pm, writes Ke > 1
//    into emissiveFactor, which glTF bounds by 1, and marks cut-outs BLEND):
//    - conductors (illum 3/5/8): metallic 1, baseColor = Ks;
//    - other materials: metallic 0, and KHR_materials_specular: no lobe where Ks = 0, else a
//      lobe of F0 = Ks (specularColorFactor = Ks / 0.04);
//    - roughness = Pr, or from Ns as stereotrace's OBJ reader derives it;
//    - Ke as emissiveFactor (<= 1) x KHR_materials_emissive_strength;
//    - opacity masks (map_d, d < 1) and glass as alphaMode MASK at 0.5;
//    - the whole scene under one node scaled to metres (camera.json's meters_per_unit),
//      since glTF is in metres and obj2gltf keeps the OBJ's numbers.
//    camera.json and lights.json are copied beside scene.glb (with any image lights.json
//    names): what glTF cannot say (environment maps, sky) stays in the sidecar files.
// 3. `cornell-box-punctual`: the Cornell box with its camera and two KHR_lights_punctual
//    lights (a point and a spot) written into the glTF file itself, no sidecar files; and
//    beside it `cornell-box-punctual-obj`, the same scene as an OBJ folder whose lights.json
//    states the same lights, for the comparison.
// 4. The Khronos glTF-Validator checks every file written; an error fails the script.
//
// Writes OUT/<scene>/scene.glb and OUT/validation.json.

import fs from "node:fs";
import path from "node:path";
import { createRequire } from "node:module";

// Copies a file and makes the copy writable (the shared scenes are read-only).
function copy(from, to) {
  fs.copyFileSync(from, to);
  fs.chmodSync(to, 0o644);
}
import { NodeIO } from "@gltf-transform/core";
import {
  KHRLightsPunctual,
  KHRMaterialsEmissiveStrength,
  KHRMaterialsSpecular,
} from "@gltf-transform/extensions";

const require = createRequire(import.meta.url);
const obj2gltf = require("obj2gltf");
const validator = require("gltf-validator");

const MIRROR_MAX_ROUGHNESS = 0.02;

// The MTL's materials: name -> { Kd, Ks, Ke, Ns, Pr, Pm, illum, d, map_Kd, map_d }.
function parseMtl(file) {
  const out = {};
  let cur = null;
  for (const raw of fs.readFileSync(file, "utf8").split(/\r?\n/)) {
    const line = raw.trim();
    if (!line || line.startsWith("#")) continue;
    const [key, ...rest] = line.split(/\s+/);
    const nums = rest.map(Number);
    if (key === "newmtl") {
      cur = out[rest.join(" ")] = {};
    } else if (cur && ["Kd", "Ks", "Ke"].includes(key)) {
      cur[key] = nums.length === 1 ? [nums[0], nums[0], nums[0]] : nums.slice(0, 3);
    } else if (cur && ["Ns", "Pr", "Pm", "illum", "d", "Tr"].includes(key)) {
      cur[key] = nums[0];
    } else if (cur && (key === "map_Kd" || key === "map_d")) {
      cur[key] = rest[rest.length - 1];
    }
  }
  return out;
}

const clamp01 = (v) => Math.min(1, Math.max(0, v));

function roughnessOf(m) {
  if (m.Pr !== undefined) return clamp01(m.Pr);
  if (m.Ns !== undefined) return clamp01(Math.sqrt(Math.sqrt(2 / (Math.max(m.Ns, 0) + 2))));
  return 1;
}

// Rewrites each material from its MTL entry (see the notes at the top).
function applyMtl(doc, mtl) {
  const specularExt = doc.createExtension(KHRMaterialsSpecular);
  const strengthExt = doc.createExtension(KHRMaterialsEmissiveStrength);
  for (const material of doc.getRoot().listMaterials()) {
    // obj2gltf names copies of a material used by several OBJ groups `name-2`, `name-3`, ...
    const name = material.getName();
    const m = mtl[name] ?? mtl[name.replace(/-\d+$/, "")];
    if (!m) throw new Error(`material ${name} is not in the MTL`);
    const kd = (m.Kd ?? [0.8, 0.8, 0.8]).map(clamp01);
    const ks = (m.Ks ?? [0, 0, 0]).map(clamp01);
    const illum = m.illum ?? (Math.max(...ks) > 0 ? 2 : 1);
    const roughness = roughnessOf(m);
    const glass = [4, 6, 7, 9].includes(illum);
    const conductor = [3, 5, 8].includes(illum);
    const opacity = glass ? 0 : clamp01(m.d ?? (m.Tr !== undefined ? 1 - m.Tr : 1));
    const base = material.getBaseColorFactor();
    if (conductor) {
      material.setMetallicFactor(1).setRoughnessFactor(roughness).setBaseColorFactor([...ks, opacity]);
      material.setBaseColorTexture(null);
    } else {
      material.setMetallicFactor(0).setRoughnessFactor(roughness);
      // map_Kd replaces Kd (the MTL's convention); obj2gltf already wrote a factor of 1 then.
      const colour = material.getBaseColorTexture() ? base.slice(0, 3) : kd;
      material.setBaseColorFactor([...colour, opacity]);
      const lobe = illum === 2 && Math.max(...ks) > 0;
      const spec = specularExt.createSpecular();
      if (lobe) spec.setSpecularFactor(1).setSpecularColorFactor(ks.map((k) => k / 0.04));
      else spec.setSpecularFactor(0);
      material.setExtension("KHR_materials_specular", spec);
    }
    const ke = (m.Ke ?? [0, 0, 0]).map((v) => Math.max(0, v));
    const peak = Math.max(...ke);
    material.setEmissiveTexture(null);
    if (peak > 0) {
      material.setEmissiveFactor(ke.map((v) => v / peak));
      if (peak !== 1) material.setExtension("KHR_materials_emissive_strength", strengthExt.createEmissiveStrength().setEmissiveStrength(peak));
    } else {
      material.setEmissiveFactor([0, 0, 0]);
    }
    const cutout = glass || opacity < 1 || m.map_d !== undefined;
    material.setAlphaMode(cutout ? "MASK" : "OPAQUE").setAlphaCutoff(0.5);
    // Reflection is two-sided in stereotrace whatever this says; emitters are one-sided.
    material.setDoubleSided(false);
  }
}

// Puts every root node under one node scaled by `metres` per unit.
function scaleToMetres(doc, metres) {
  const scene = doc.getRoot().getDefaultScene() ?? doc.getRoot().listScenes()[0];
  const root = doc.createNode("to-metres").setScale([metres, metres, metres]);
  for (const child of scene.listChildren()) {
    scene.removeChild(child);
    root.addChild(child);
  }
  scene.addChild(root);
  return scene;
}

const sub = (a, b) => a.map((v, i) => v - b[i]);
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const normalize = (a) => {
  const l = Math.hypot(...a);
  return a.map((v) => v / l);
};

// The unit quaternion [x, y, z, w] of the rotation whose columns are x, y, z.
function quaternionOfBasis(x, y, z) {
  const [m00, m10, m20] = x;
  const [m01, m11, m21] = y;
  const [m02, m12, m22] = z;
  const trace = m00 + m11 + m22;
  let q;
  if (trace > 0) {
    const s = Math.sqrt(trace + 1) * 2;
    q = [(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s];
  } else if (m00 > m11 && m00 > m22) {
    const s = Math.sqrt(1 + m00 - m11 - m22) * 2;
    q = [0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s];
  } else if (m11 > m22) {
    const s = Math.sqrt(1 + m11 - m00 - m22) * 2;
    q = [(m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s];
  } else {
    const s = Math.sqrt(1 + m22 - m00 - m11) * 2;
    q = [(m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s];
  }
  return normalize(q);
}

// A node at `eye` whose -Z looks along `forward` with +Y towards `up` (glTF's camera and
// light convention).
function lookNode(doc, name, eye, forward, up) {
  const back = normalize(forward.map((v) => -v));
  const right = normalize(cross(up, back));
  const trueUp = cross(back, right);
  return doc.createNode(name).setTranslation(eye).setRotation(quaternionOfBasis(right, trueUp, back));
}

async function convertObj(sceneDir) {
  const glb = await obj2gltf(path.join(sceneDir, "scene.obj"), { binary: true, checkTransparency: true });
  const io = new NodeIO().registerExtensions([KHRMaterialsSpecular, KHRMaterialsEmissiveStrength, KHRLightsPunctual]);
  const doc = await io.readBinary(new Uint8Array(glb));
  doc.getRoot().getAsset().generator = "obj2gltf 3.2.0, then glTF-Transform 4.3.0 (stereotrace tools/gltf/convert.mjs)";
  return { io, doc };
}

async function validate(file, report) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  const result = await validator.validateBytes(bytes, { uri: path.basename(file), maxIssues: 0 });
  report[file] = { errors: result.issues.numErrors, warnings: result.issues.numWarnings, messages: result.issues.messages.filter((m) => m.severity === 0) };
  if (result.issues.numErrors > 0) {
    console.error(JSON.stringify(result.issues.messages.slice(0, 10), null, 2));
    throw new Error(`${file}: the Khronos glTF-Validator found ${result.issues.numErrors} error(s)`);
  }
  const triangles = result.info?.totalTriangleCount ?? "?";
  console.log(`${file}: valid (${result.issues.numWarnings} warnings, ${triangles} triangles)`);
}

async function convertShared(shared, out, name, report) {
  const sceneDir = path.join(shared, name);
  const camera = JSON.parse(fs.readFileSync(path.join(sceneDir, "camera.json"), "utf8"));
  const { io, doc } = await convertObj(sceneDir);
  applyMtl(doc, parseMtl(path.join(sceneDir, "scene.mtl")));
  scaleToMetres(doc, camera.meters_per_unit ?? 1);
  const dir = path.join(out, name);
  fs.mkdirSync(dir, { recursive: true });
  await io.write(path.join(dir, "scene.glb"), doc);
  copy(path.join(sceneDir, "camera.json"), path.join(dir, "camera.json"));
  const lightsFile = path.join(sceneDir, "lights.json");
  if (fs.existsSync(lightsFile)) {
    copy(lightsFile, path.join(dir, "lights.json"));
    for (const light of JSON.parse(fs.readFileSync(lightsFile, "utf8"))) {
      if (light.filename) copy(path.join(sceneDir, light.filename), path.join(dir, light.filename));
    }
  }
  await validate(path.join(dir, "scene.glb"), report);
}

// The punctual lights of the Cornell variant, in metres: a point light and a spot pointing down.
const POINT = { position: [0.18, 0.42, 0.2], intensity: [0.12, 0.1, 0.08] };
const SPOT = { position: [0.38, 0.5, 0.32], intensity: [0.4, 0.4, 0.45], inner_deg: 15, outer_deg: 30 };

async function cornellPunctual(shared, out, report) {
  const sceneDir = path.join(shared, "cornell-box");
  const camera = JSON.parse(fs.readFileSync(path.join(sceneDir, "camera.json"), "utf8"));
  const mpu = camera.meters_per_unit ?? 1;
  const { io, doc } = await convertObj(sceneDir);
  applyMtl(doc, parseMtl(path.join(sceneDir, "scene.mtl")));
  const scene = scaleToMetres(doc, mpu);
  const eye = camera.eye.map((v) => v * mpu);
  const forward = normalize(sub(camera.target.map((v) => v * mpu), eye));
  const cam = doc
    .createCamera("camera")
    .setType("perspective")
    .setYFov((camera.vfov_deg * Math.PI) / 180)
    .setZNear(0.01)
    .setAspectRatio((camera.width ?? 1) / (camera.height ?? 1));
  scene.addChild(lookNode(doc, "camera", eye, forward, camera.up).setCamera(cam));
  const lights = doc.createExtension(KHRLightsPunctual);
  const peak = (v) => Math.max(...v);
  const point = lights.createLight("point").setType("point").setIntensity(peak(POINT.intensity)).setColor(POINT.intensity.map((v) => v / peak(POINT.intensity)));
  scene.addChild(doc.createNode("point").setTranslation(POINT.position).setExtension("KHR_lights_punctual", point));
  const spot = lights
    .createLight("spot")
    .setType("spot")
    .setIntensity(peak(SPOT.intensity))
    .setColor(SPOT.intensity.map((v) => v / peak(SPOT.intensity)))
    .setInnerConeAngle((SPOT.inner_deg * Math.PI) / 180)
    .setOuterConeAngle((SPOT.outer_deg * Math.PI) / 180);
  // Pointing straight down: the node's -Z along -Y, its +Y along -Z.
  scene.addChild(lookNode(doc, "spot", SPOT.position, [0, -1, 0], [0, 0, -1]).setExtension("KHR_lights_punctual", spot));
  const dir = path.join(out, "cornell-box-punctual");
  fs.mkdirSync(dir, { recursive: true });
  await io.write(path.join(dir, "scene.glb"), doc);
  await validate(path.join(dir, "scene.glb"), report);

  // The same scene as an OBJ folder (stereotrace's lights.json extensions), positions in the
  // OBJ's units.
  const twin = path.join(out, "cornell-box-punctual-obj");
  fs.mkdirSync(twin, { recursive: true });
  for (const f of ["scene.obj", "scene.mtl", "camera.json", "SOURCE.md"]) copy(path.join(sceneDir, f), path.join(twin, f));
  const area = JSON.parse(fs.readFileSync(path.join(sceneDir, "lights.json"), "utf8"));
  const toUnits = (p) => p.map((v) => v / mpu);
  area.push({ type: "point", position: toUnits(POINT.position), intensity: POINT.intensity });
  area.push({
    type: "spot",
    position: toUnits(SPOT.position),
    intensity: SPOT.intensity,
    direction: [0, -1, 0],
    inner_cone_deg: SPOT.inner_deg,
    outer_cone_deg: SPOT.outer_deg,
  });
  fs.writeFileSync(path.join(twin, "lights.json"), JSON.stringify(area, null, 2));
}

const [shared, out, ...only] = process.argv.slice(2);
if (!shared || !out) {
  console.error("usage: node convert.mjs SHARED_SCENES OUT [SCENE...]");
  process.exit(2);
}
const scenes = only.length ? only : ["cornell-box", "bunny", "sponza", "living-room", "classroom", "cornell-box-punctual"];
const report = {};
for (const name of scenes) {
  if (name === "cornell-box-punctual") await cornellPunctual(shared, out, report);
  else await convertShared(shared, out, name, report);
}
fs.writeFileSync(path.join(out, "validation.json"), JSON.stringify(report, null, 2));
