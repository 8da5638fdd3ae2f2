-- wrk script of the soak test: a fixed, interleaved mix of requests (per 20 requests: 12
-- valid classifications with the default model, 2 with ward11, a corrupt image, a missing
-- image, an unknown model, a body over the limit, a bad white, GET /v1/models and
-- GET /health/ready); with ONLY_VALID set (the overload phase), valid classifications only.
-- Prints the status counts of all threads and the latency percentiles.
-- Files: IMAGE (a valid PNG sphere), CORRUPT (a truncated one), BIG (over the body limit).
local function read(path)
  local f = assert(io.open(path, "rb"))
  local data = f:read("*all")
  f:close()
  return data
end

local boundary = "----reflectance-soak-5e1d"
local content_type = "multipart/form-data; boundary=" .. boundary
local function text(name, value)
  return "--" .. boundary .. "\r\nContent-Disposition: form-data; name=\"" .. name .. "\"\r\n\r\n" .. value .. "\r\n"
end
local function file(name, bytes)
  return "--" .. boundary .. "\r\nContent-Disposition: form-data; name=\"" .. name
    .. "\"; filename=\"f\"\r\nContent-Type: application/octet-stream\r\n\r\n" .. bytes .. "\r\n"
end
local circle = text("cx", "127.5") .. text("cy", "127.5") .. text("r", "116")
local close = "--" .. boundary .. "--\r\n"

local threads = {}
setup = function(thread)
  table.insert(threads, thread)
end

local pattern
local n = 0
statuses = {}

init = function(args)
  local image, corrupt, big = read(os.getenv("IMAGE")), read(os.getenv("CORRUPT")), read(os.getenv("BIG"))
  local h = { ["Content-Type"] = content_type }
  local valid = wrk.format("POST", "/v1/classify", h, file("image", image) .. text("white", "0.9") .. circle .. close)
  local ward11 = wrk.format("POST", "/v1/models/ward11/classify", h, file("image", image) .. text("white", "0.9") .. circle .. close)
  local bad_image = wrk.format("POST", "/v1/classify", h, file("image", corrupt) .. circle .. close)
  local missing = wrk.format("POST", "/v1/classify", h, text("white", "0.9") .. circle .. close)
  local unknown = wrk.format("POST", "/v1/models/nope/classify", h, file("image", image) .. circle .. close)
  local oversized = wrk.format("POST", "/v1/classify", h, file("image", big) .. circle .. close)
  local bad_white = wrk.format("POST", "/v1/classify", h, file("image", image) .. text("white", "-1") .. circle .. close)
  local models = wrk.format("GET", "/v1/models")
  local ready = wrk.format("GET", "/health/ready")
  pattern = { valid, valid, ward11, valid, bad_image, valid, valid, missing, valid, models,
              valid, ward11, valid, unknown, valid, oversized, valid, bad_white, valid, ready }
  if os.getenv("ONLY_VALID") then
    pattern = { valid }
  end
end

request = function()
  n = n + 1
  return pattern[(n - 1) % #pattern + 1]
end

response = function(status, headers, body)
  statuses[status] = (statuses[status] or 0) + 1
end

done = function(summary, latency, requests)
  local total = {}
  for _, thread in ipairs(threads) do
    for status, count in pairs(thread:get("statuses")) do
      total[status] = (total[status] or 0) + count
    end
  end
  local keys = {}
  for status in pairs(total) do table.insert(keys, status) end
  table.sort(keys)
  local parts = {}
  for _, status in ipairs(keys) do table.insert(parts, status .. "=" .. total[status]) end
  io.write("statuses: " .. table.concat(parts, " ") .. "\n")
  io.write(string.format("requests: %d  rps: %.1f  p50_ms: %.2f  p99_ms: %.2f  max_ms: %.2f\n",
    summary.requests, summary.requests / (summary.duration / 1e6),
    latency:percentile(50) / 1000, latency:percentile(99) / 1000, latency.max / 1000))
  io.write(string.format("socket_errors: connect=%d read=%d write=%d timeout=%d\n",
    summary.errors.connect, summary.errors.read, summary.errors.write, summary.errors.timeout))
end
