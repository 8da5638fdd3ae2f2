-- wrk script: POST a multipart classification request (the image and its fields) to
-- /v1/classify. The image path comes from the IMAGE environment variable, its media type from
-- IMAGE_TYPE, the other fields from FIELDS ("white=0.9 cx=127.5 cy=127.5 r=116").
package.path = "scripts/loadtest/?.lua;" .. package.path
require "report"

local image = read_image()
local boundary = "----reflectance-wrk-7f3a9c"
local function field(name, value)
  return "--" .. boundary .. "\r\nContent-Disposition: form-data; name=\"" .. name .. "\"\r\n\r\n" .. value .. "\r\n"
end

local body = "--" .. boundary .. "\r\n"
  .. "Content-Disposition: form-data; name=\"image\"; filename=\"image\"\r\n"
  .. "Content-Type: " .. (os.getenv("IMAGE_TYPE") or "image/png") .. "\r\n\r\n" .. image .. "\r\n"
for _, f in ipairs(request_fields()) do
  body = body .. field(f[1], f[2])
end

wrk.method = "POST"
wrk.headers["Content-Type"] = "multipart/form-data; boundary=" .. boundary
wrk.body = body .. "--" .. boundary .. "--\r\n"
