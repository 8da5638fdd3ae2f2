-- wrk script: the same classification as classify.lua, as an Open Inference Protocol request
-- with the binary tensor data extension (what tritonclient sends by default): a JSON header,
-- then the image as one BYTES element (its 4-byte little-endian length, then its bytes).
-- The image path comes from the IMAGE environment variable, the other inputs (FP64 scalars)
-- from FIELDS.
package.path = "scripts/loadtest/?.lua;" .. package.path
require "report"

local image = read_image()
local function le32(n)
  return string.char(n % 256, math.floor(n / 256) % 256, math.floor(n / 65536) % 256,
    math.floor(n / 16777216) % 256)
end
local function scalar(name, value)
  return string.format('{"name":"%s","datatype":"FP64","shape":[1],"data":[%s]}', name, value)
end
local header = '{"inputs":[{"name":"image","datatype":"BYTES","shape":[1],'
  .. '"parameters":{"binary_data_size":' .. (#image + 4) .. '}}'
for _, f in ipairs(request_fields()) do
  header = header .. "," .. scalar(f[1], f[2])
end
header = header .. "]}"

wrk.method = "POST"
wrk.headers["Content-Type"] = "application/octet-stream"
wrk.headers["Inference-Header-Content-Length"] = tostring(#header)
wrk.body = header .. le32(#image) .. image
