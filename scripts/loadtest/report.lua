-- What every load-test script reports: requests/s, latency percentiles, errors.
local statuses = {}

function response(status, headers, body)
  statuses[status] = (statuses[status] or 0) + 1
end

function done(summary, latency, requests)
  io.write(string.format("requests/s: %.1f\n", summary.requests / (summary.duration / 1e6)))
  io.write(string.format("latency p50: %.2f ms  p90: %.2f ms  p99: %.2f ms  max: %.2f ms\n",
    latency:percentile(50) / 1000, latency:percentile(90) / 1000,
    latency:percentile(99) / 1000, latency.max / 1000))
  io.write(string.format("errors: connect %d, read %d, write %d, timeout %d, non-2xx %d\n",
    summary.errors.connect, summary.errors.read, summary.errors.write,
    summary.errors.timeout, summary.errors.status))
end

-- The file named by the IMAGE environment variable.
function read_image()
  local f = assert(io.open(assert(os.getenv("IMAGE"), "IMAGE is not set"), "rb"))
  local image = f:read("*all")
  f:close()
  return image
end

-- The request's fields besides the image, from the FIELDS environment variable
-- ("white=0.9 cx=127.5 ..."), in their order, as {name, value} pairs.
function request_fields()
  local fields = {}
  for name, value in string.gmatch(os.getenv("FIELDS") or "", "([%w_]+)=([^%s]+)") do
    fields[#fields + 1] = {name, value}
  end
  return fields
end
