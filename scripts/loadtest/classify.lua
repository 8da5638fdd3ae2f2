-- wrk script: POST a multipart classification request (image + white + circle).
-- The image path comes from the IMAGE environment variable.
local path = os.getenv("IMAGE")
local f = assert(io.open(path, "rb"))
local image = f:read("*all")
f:close()

local boundary = "----reflectance-wrk-7f3a9c"
local function field(name, value)
  return "--" .. boundary .. "\r\nContent-Disposition: form-data; name=\"" .. name .. "\"\r\n\r\n" .. value .. "\r\n"
end

wrk.method = "POST"
wrk.headers["Content-Type"] = "multipart/form-data; boundary=" .. boundary
wrk.body = "--" .. boundary .. "\r\n"
  .. "Content-Disposition: form-data; name=\"image\"; filename=\"sphere.png\"\r\n"
  .. "Content-Type: image/png\r\n\r\n" .. image .. "\r\n"
  .. field("white", "0.9") .. field("cx", "127.5") .. field("cy", "127.5") .. field("r", "116")
  .. "--" .. boundary .. "--\r\n"

local statuses = {}
response = function(status, headers, body)
  statuses[status] = (statuses[status] or 0) + 1
end

done = function(summary, latency, requests)
  io.write(string.format("requests/s: %.1f\n", summary.requests / (summary.duration / 1e6)))
  io.write(string.format("latency p50: %.2f ms  p90: %.2f ms  p99: %.2f ms  max: %.2f ms\n",
    latency:percentile(50) / 1000, latency:percentile(90) / 1000,
    latency:percentile(99) / 1000, latency.max / 1000))
  io.write(string.format("errors: connect %d, read %d, write %d, timeout %d, non-2xx %d\n",
    summary.errors.connect, summary.errors.read, summary.errors.write,
    summary.errors.timeout, summary.errors.status))
end
