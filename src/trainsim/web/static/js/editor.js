// Editable tables for a trainsim/train or trainsim/route mapping, built from its JSON schema
// (GET /api/schema/train|route). Every input carries data-path, the field path of the core's
// messages (formation[1].mass_t), so that a validation error is shown next to its field.
//
// Scalars of an object form a small form; lists of objects are tables (one row per entry); a
// speed/force table is a two-column table; a choice between models (traction model, resistance
// family) is a select that switches the fields below it.

const HIDDEN = new Set(["schema", "version"]);
// optional lists shown only when the file has them (they replace a more usual list)
const ONLY_IF_PRESENT = new Set(["elevation", "force_n"]);

const el = (tag, attrs = {}, ...children) => {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") node.className = v;
    else if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) node.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children) if (c !== null && c !== undefined) node.append(c);
  return node;
};

const join = (path, key) => (typeof key === "number" ? `${path}[${key}]` : path ? `${path}.${key}` : key);

const isNum = (x) => typeof x === "number" && Number.isFinite(x);

// A table with one more row that is valid where the last one is: a copy of the last row with a
// unique name, placed where positions still increase (between the last two positions, or the last
// from-to section split in two halves).
export function withNewRow(rows, empty) {
  const n = rows.length;
  if (!n) return [structuredClone(empty)];
  const out = rows.map((r) => r);
  const row = structuredClone(rows[n - 1]);
  if (typeof row.name === "string") {
    const names = new Set(rows.map((r) => r.name));
    let k = 2;
    const base = row.name.replace(/ \(\d+\)$/, "");
    while (names.has(`${base} (${k})`)) k++;
    row.name = `${base} (${k})`;
  }
  if (isNum(row.from_m) && isNum(row.to_m) && row.to_m > row.from_m) {
    const mid = Math.round(((row.from_m + row.to_m) / 2) * 1000) / 1000;
    out[n - 1] = { ...rows[n - 1], to_m: mid };
    row.from_m = mid;
    out.push(row);
    return out;
  }
  const pos = ["position_m", "from_m"].find((k) => isNum(row[k]));
  if (pos && n >= 2 && isNum(rows[n - 2][pos]) && rows[n - 2][pos] < row[pos]) {
    row[pos] = Math.round(((rows[n - 2][pos] + row[pos]) / 2) * 1000) / 1000;
    out.splice(n - 1, 0, row);
    return out;
  }
  if (pos) row[pos] += 100;
  out.push(row);
  return out;
}

export class SpecEditor {
  constructor(root, schema, onChange) {
    this.root = root;
    this.schema = schema;
    this.defs = schema.$defs || {};
    this.onChange = onChange;
    this.data = null;
    this.errorNodes = [];
  }

  // ------------------------------------------------------------ schema helpers
  resolve(node) {
    // -> {node, optional}; $ref resolved, anyOf [X, null] unwrapped
    let optional = false;
    for (let i = 0; i < 5 && node; i++) {
      if (node.$ref) node = this.defs[node.$ref.split("/").pop()];
      else if (node.anyOf && node.anyOf.some((x) => x.type === "null")) {
        const rest = node.anyOf.filter((x) => x.type !== "null");
        optional = true;
        node = rest.length === 1 ? rest[0] : { oneOf: rest };
      } else break;
    }
    return { node, optional };
  }

  variants(node) {
    // union -> [{tag, schema}] ; tag "none" for a const string option
    const out = [];
    const key = node.discriminator ? node.discriminator.propertyName : null;
    for (const option of node.oneOf || []) {
      const { node: r } = this.resolve(option);
      if (r.const !== undefined) {
        out.push({ tag: r.const, schema: null, key });
        continue;
      }
      const props = r.properties || {};
      const tagKey = key || Object.keys(props).find((k) => props[k].const !== undefined || props[k].enum);
      const tagSchema = props[tagKey] || {};
      const tags = tagSchema.const !== undefined ? [tagSchema.const] : tagSchema.enum || [];
      for (const tag of tags) out.push({ tag, schema: r, key: tagKey });
    }
    return out;
  }

  isUnion(node) {
    return Boolean(node && node.oneOf);
  }

  isScalar(node) {
    return node && !node.oneOf && ["number", "integer", "string", "boolean"].includes(node.type || (node.enum ? "string" : ""));
  }

  // ------------------------------------------------------------ data helpers
  changed(structural = false) {
    if (structural) this.render();
    this.onChange(this.data);
  }

  parseInput(raw, node) {
    const text = raw.trim();
    if (text === "") return undefined;
    if (node.type === "number" || node.type === "integer") {
      const n = Number(text);
      return Number.isFinite(n) ? n : text; // text goes to the server, which names the problem
    }
    return text;
  }

  // ------------------------------------------------------------ rendering
  setData(data) {
    this.data = data;
    this.render();
  }

  render() {
    this.errorNodes = [];
    this.root.replaceChildren();
    if (!this.data) return;
    this.renderObject(this.root, this.schema, this.data, "", null);
  }

  scalarInput(node, obj, key, path, optional) {
    const value = obj[key];
    const set = (v) => {
      if (v === undefined) delete obj[key];
      else obj[key] = v;
      this.changed();
    };
    let input;
    if (node.type === "boolean") {
      input = el("input", { type: "checkbox", "data-path": path });
      input.checked = Boolean(value ?? node.default);
      input.addEventListener("change", () => set(input.checked));
    } else if (node.enum) {
      input = el("select", { "data-path": path });
      if (optional || value === undefined) input.append(el("option", { value: "", text: "" }));
      for (const option of node.enum) input.append(el("option", { value: option, text: option }));
      input.value = value ?? "";
      input.addEventListener("change", () => set(input.value === "" ? undefined : input.value));
    } else {
      const numeric = node.type === "number" || node.type === "integer";
      input = el("input", {
        type: "text",
        "data-path": path,
        inputmode: numeric ? "decimal" : undefined,
        class: numeric ? "num" : "txt",
        placeholder: node.default !== undefined && node.default !== null ? String(node.default) : optional ? "—" : "",
      });
      input.value = value === undefined || value === null ? "" : String(value);
      input.addEventListener("change", () => set(this.parseInput(input.value, node)));
    }
    input.title = path;
    return input;
  }

  renderObject(container, node, obj, path, skipKey) {
    const props = node.properties || {};
    const form = el("div", { class: "form" });
    const blocks = [];
    for (const [key, raw] of Object.entries(props)) {
      if (HIDDEN.has(key) || key === skipKey) continue;
      const { node: child, optional } = this.resolve(raw);
      const p = join(path, key);
      if (this.isScalar(child)) {
        form.append(el("label", { class: "field" }, el("span", { class: "name", text: key }),
          this.scalarInput(child, obj, key, p, optional)));
      } else if (child && child.type === "array" && this.isScalar(this.resolve(child.items || {}).node)) {
        if (key === "speed_kmh") blocks.push(() => this.renderPairs(obj, path, props));
        else if (!["force_kn", "force_n"].includes(key) && (!ONLY_IF_PRESENT.has(key) || obj[key])) {
          blocks.push(() => this.renderList(obj, key, p));
        }
      } else if (child && child.type === "array") {
        if (ONLY_IF_PRESENT.has(key) && !obj[key]) continue;
        blocks.push(() => this.renderTable(obj, key, p, this.resolve(child.items).node, optional));
      } else if (this.isUnion(child)) {
        blocks.push(() => this.renderUnion(obj, key, p, child, optional));
      } else if (child && child.properties) {
        blocks.push(() => this.renderNested(obj, key, p, child, optional));
      }
    }
    if (form.children.length) container.append(form);
    for (const make of blocks) container.append(make());
  }

  section(title, path, ...children) {
    return el("fieldset", { class: "section", "data-path": path }, el("legend", { text: title }), ...children);
  }

  renderNested(obj, key, path, node, optional) {
    const box = this.section(key, path);
    if (optional) {
      const toggle = el("input", { type: "checkbox", "data-path": `${path}.__present` });
      toggle.checked = obj[key] !== undefined && obj[key] !== null;
      toggle.addEventListener("change", () => {
        if (toggle.checked) obj[key] = {};
        else delete obj[key];
        this.changed(true);
      });
      box.append(el("label", { class: "toggle" }, toggle, ` ${key} given`));
    }
    if (obj[key] && typeof obj[key] === "object") this.renderObject(box, node, obj[key], path, null);
    return box;
  }

  renderUnion(obj, key, path, node, optional) {
    const variants = this.variants(node);
    const value = obj[key];
    const current = value === undefined || value === null ? null : typeof value === "object" ? value[variants.find((v) => v.schema)?.key] : value;
    const select = el("select", { "data-path": `${path}.${variants.find((v) => v.schema)?.key || "model"}` });
    if (optional || current === null) select.append(el("option", { value: "", text: optional ? "(not given)" : "(choose)" }));
    for (const v of variants) select.append(el("option", { value: v.tag, text: v.tag }));
    select.value = current ?? "";
    select.addEventListener("change", () => {
      const chosen = variants.find((v) => v.tag === select.value);
      if (!chosen) delete obj[key];
      else if (!chosen.schema) obj[key] = chosen.tag;
      else {
        // keep the fields both models have (e.g. a braking table when switching table <-> fraction_of_full)
        const keep = {};
        const old = typeof value === "object" && value ? value : {};
        for (const k of Object.keys(chosen.schema.properties || {})) if (k in old) keep[k] = old[k];
        obj[key] = { ...keep, [chosen.key]: chosen.tag };
      }
      this.changed(true);
    });
    const box = this.section(key, path, el("label", { class: "field" }, el("span", { class: "name", text: "model" }), select));
    const chosen = variants.find((v) => v.tag === current);
    if (chosen && chosen.schema && typeof value === "object") this.renderObject(box, chosen.schema, value, path, chosen.key);
    return box;
  }

  rowButtons(onDelete) {
    return el("td", { class: "row-actions" }, el("button", { type: "button", class: "icon", title: "delete row", text: "×", onclick: onDelete }));
  }

  renderPairs(obj, path, props) {
    // a speed/force table: speed_kmh[] with force_kn[] (or force_n[])
    const fkey = obj.force_n && !obj.force_kn ? "force_n" : "force_kn";
    const speeds = (obj.speed_kmh = obj.speed_kmh || []);
    const forces = (obj[fkey] = obj[fkey] || []);
    const table = el("table", { class: "grid", "data-path": join(path, "speed_kmh") });
    table.append(el("tr", {}, el("th", { text: "speed_kmh" }), el("th", { text: fkey }), el("th")));
    const n = Math.max(speeds.length, forces.length);
    for (let i = 0; i < n; i++) {
      const cell = (arr, key) => {
        const p = `${join(path, key)}[${i}]`;
        const input = el("input", { type: "text", class: "num", inputmode: "decimal", "data-path": p, title: p });
        input.value = arr[i] ?? "";
        input.addEventListener("change", () => {
          arr[i] = this.parseInput(input.value, { type: "number" }) ?? null;
          this.changed();
        });
        return el("td", {}, input);
      };
      table.append(el("tr", { "data-path": `${join(path, "speed_kmh")}[${i}]` }, cell(speeds, "speed_kmh"), cell(forces, fkey),
        this.rowButtons(() => { speeds.splice(i, 1); forces.splice(i, 1); this.changed(true); })));
    }
    const add = el("button", { type: "button", class: "add", text: "+ row", onclick: () => {
      const last = speeds.length ? Number(speeds[speeds.length - 1]) || 0 : -10;
      speeds.push(last + 10);
      forces.push(forces.length ? forces[forces.length - 1] : 0);
      this.changed(true);
    } });
    return el("div", { class: "table-block" }, el("div", { class: "caption", text: "table (linear interpolation)" }), table, add);
  }

  renderList(obj, key, path) {
    // a list of numbers (rare): one input with comma-separated values
    const input = el("input", { type: "text", class: "txt", "data-path": path, title: path });
    input.value = (obj[key] || []).join(", ");
    input.addEventListener("change", () => {
      const parts = input.value.split(",").map((x) => x.trim()).filter((x) => x !== "");
      obj[key] = parts.map((x) => (Number.isFinite(Number(x)) ? Number(x) : x));
      this.changed();
    });
    return el("label", { class: "field wide" }, el("span", { class: "name", text: key }), input);
  }

  renderTable(obj, key, path, itemNode, optional) {
    const rows = Array.isArray(obj[key]) ? obj[key] : [];
    const union = this.isUnion(itemNode);
    const variants = union ? this.variants(itemNode) : [];
    const tagKey = union ? variants[0].key : null;
    // columns: scalar fields of the item (for a union: the tag and the fields all variants share)
    let columns = [];
    if (union) {
      const shared = variants.map((v) => Object.keys(v.schema.properties)).reduce((a, b) => a.filter((k) => b.includes(k)));
      columns = [tagKey, ...shared.filter((k) => k !== tagKey)];
    } else {
      columns = Object.entries(itemNode.properties || {}).filter(([, s]) => this.isScalar(this.resolve(s).node)).map(([k]) => k);
    }
    const nested = union ? [] : Object.entries(itemNode.properties || {}).filter(([, s]) => !this.isScalar(this.resolve(s).node)).map(([k]) => k);
    const table = el("table", { class: "grid", "data-path": path });
    const head = el("tr", {}, el("th", { text: "#" }), ...columns.map((c) => el("th", { text: c })));
    if (union) head.append(el("th", { text: "coefficients" }));
    for (const k of nested) head.append(el("th", { text: k }));
    head.append(el("th"));
    table.append(head);
    rows.forEach((row, i) => {
      const rp = `${path}[${i}]`;
      const tr = el("tr", { "data-path": rp }, el("td", { class: "idx", text: String(i) }));
      const variant = union ? variants.find((v) => v.tag === row[tagKey]) : null;
      const schemaOf = (c) => this.resolve((variant ? variant.schema : itemNode).properties?.[c] || { type: "string" });
      for (const c of columns) {
        if (union && c === tagKey) {
          const select = el("select", { "data-path": `${rp}.${c}` });
          if (!variant) select.append(el("option", { value: "", text: "(choose)" }));
          for (const v of variants) select.append(el("option", { value: v.tag, text: v.tag }));
          select.value = row[tagKey] ?? "";
          select.addEventListener("change", () => {
            const keep = {};
            for (const k of columns) if (k in row && k !== tagKey) keep[k] = row[k];
            rows[i] = { [tagKey]: select.value, ...keep };
            this.changed(true);
          });
          tr.append(el("td", {}, select));
        } else {
          const { node: s, optional: opt } = schemaOf(c);
          tr.append(el("td", {}, this.scalarInput(s, row, c, `${rp}.${c}`, opt)));
        }
      }
      if (union) {
        const cell = el("td", { class: "coefs" });
        if (variant) {
          for (const [k, raw] of Object.entries(variant.schema.properties)) {
            if (columns.includes(k)) continue;
            const { node: s, optional: opt } = this.resolve(raw);
            if (!this.isScalar(s)) continue;
            cell.append(el("label", { class: "coef" }, el("span", { class: "name", text: k }), this.scalarInput(s, row, k, `${rp}.${k}`, opt)));
          }
        }
        tr.append(cell);
      }
      for (const k of nested) {
        const v = row[k];
        tr.append(el("td", { class: "muted", "data-path": `${rp}.${k}`, text: Array.isArray(v) && v.length ? `${v.length} (edit in the downloaded file)` : "—" }));
      }
      tr.append(this.rowButtons(() => {
        rows.splice(i, 1);
        if (!rows.length && optional) delete obj[key];
        this.changed(true);
      }));
      table.append(tr);
    });
    const add = el("button", { type: "button", class: "add", text: "+ row", onclick: () => {
      obj[key] = withNewRow(rows, union ? { [tagKey]: variants[0].tag } : {});
      this.changed(true);
    } });
    return this.section(key, path, table, add);
  }

  // ------------------------------------------------------------ errors
  clearErrors() {
    for (const node of this.errorNodes) {
      if (node.classList.contains("field-error")) node.remove();
      else node.classList.remove("invalid");
    }
    this.errorNodes = [];
  }

  find(field) {
    // the element of a field path, or of its nearest parent shown
    let p = field || "";
    while (p) {
      const found = this.root.querySelector(`[data-path="${CSS.escape(p)}"]`);
      if (found) return found;
      const cut = Math.max(p.lastIndexOf("."), p.lastIndexOf("["));
      if (cut <= 0) break;
      p = p.slice(0, cut);
    }
    return null;
  }

  showErrors(detail) {
    this.clearErrors();
    const unplaced = [];
    for (const d of detail || []) {
      const target = this.find(d.field);
      if (!target) {
        unplaced.push(d);
        continue;
      }
      target.classList.add("invalid");
      this.errorNodes.push(target);
      const msg = el("div", { class: "field-error", role: "alert", "data-field": d.field || "", text: d.msg });
      if (["INPUT", "SELECT"].includes(target.tagName)) target.insertAdjacentElement("afterend", msg);
      else if (target.tagName === "TR") target.lastElementChild.append(msg);
      else if (target.tagName === "TABLE") target.insertAdjacentElement("afterend", msg);
      else target.append(msg);
      this.errorNodes.push(msg);
    }
    return unplaced;
  }
}
