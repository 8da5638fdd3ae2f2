-- wrk script: POST a multipart classification request (image + white + circle) to /v1/classify.
-- The image path comes from the IMAGE environment variable.
package.path = "scripts/loadtest/?.lua;" .. package.path
require "report"

local image = read_image()
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
