// The JSON API of the server (same endpoints as documented at /docs). Every call resolves to
// {ok, status, data}; error answers carry {message, detail: [{field, msg}]}.

export async function api(method, url, body) {
  const init = { method, headers: {}, credentials: "same-origin" };
  if (body instanceof FormData) {
    init.body = body;
  } else if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  let response;
  try {
    response = await fetch(url, init);
  } catch (err) {
    return { ok: false, status: 0, data: { message: `server not reachable (${err})`, detail: [] } };
  }
  let data = null;
  const type = response.headers.get("content-type") || "";
  if (type.includes("application/json")) {
    data = await response.json();
  } else if (response.status !== 204) {
    data = await response.text();
  }
  if (!response.ok && (data === null || typeof data !== "object")) {
    data = { message: `${response.status} ${response.statusText}: ${data || ""}`, detail: [] };
  }
  return { ok: response.ok, status: response.status, data };
}

export const get = (url) => api("GET", url);
export const put = (url, body) => api("PUT", url, body);
export const post = (url, body) => api("POST", url, body);
export const del = (url) => api("DELETE", url);

export async function upload(url, file) {
  const form = new FormData();
  form.append("file", file, file.name);
  return api("POST", url, form);
}
