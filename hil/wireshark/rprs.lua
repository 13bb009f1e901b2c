-- RPRS radio frames for Wireshark (docs/protocol.md section 3; docs/wireshark.md).
--
-- A capture from `rprs sim --pcap` puts each radio transmission on an interface of link type
-- USER0 (147); this dissector decodes it: Header 0F 0A 05, Destination, Source, Number,
-- Type, Length (ASCII digits), Content (commands name(args)), End 17 19. A frame that breaks
-- the format gets expert info (bad Header, a digit that is not one, a Length that does not
-- fit the bytes, a bad End, a crc() that does not match) and stays in the capture. CAN
-- frames on the same capture use Wireshark's own SocketCAN dissector for the frame, and the
-- rprs_can protocol below for the payload: every message and signal of can_bus/rprs.dbc, from
-- the generated table at the end of this file.
--
-- Display filters: rprs.src == 2, rprs.type == 4, rprs.cmd == "movex", rprs.dst == 7,
-- rprs.crc.ok == 0, rprs.auth.fresh > 0x100, rprs_can.msg == "JOINT3_CMD",
-- rprs_can.joint3_cmd.angle > 50.

-- Installed (rprs wireshark --install) and also given with -X lua_script:PATH, the file runs
-- twice in Wireshark's one Lua state: the second time it stops here, rather than failing to
-- register the protocols again (a Lua traceback on every run, an error dialog in the GUI).
for _, name in ipairs(Dissector.list()) do
    if name == "rprs" then return end
end

local rprs = Proto("rprs", "RPRS radio frame")

local type_names = {
    [0] = "seek help", [1] = "invitation", [2] = "instruction",
    [3] = "broadcast information", [4] = "failure", [5] = "boot", [6] = "join",
}

local f = rprs.fields
f.header = ProtoField.bytes("rprs.header", "Header")
f.dst = ProtoField.uint8("rprs.dst", "Destination", base.DEC)
f.src = ProtoField.uint8("rprs.src", "Source", base.DEC)
f.num = ProtoField.uint8("rprs.num", "Number", base.DEC)
f.type = ProtoField.uint8("rprs.type", "Type", base.DEC, type_names)
f.len = ProtoField.uint16("rprs.len", "Length", base.DEC)
f.content = ProtoField.string("rprs.content", "Content")
f.cmd = ProtoField.string("rprs.cmd", "Command")
f.args = ProtoField.string("rprs.args", "Arguments")
f.endmark = ProtoField.bytes("rprs.end", "End")
f.crc = ProtoField.uint16("rprs.crc", "Checksum carried by crc()", base.DEC)
f.crc_calc = ProtoField.uint16("rprs.crc.computed", "CRC-16/CCITT-FALSE of Destination..Content",
                               base.DEC)
f.crc_ok = ProtoField.bool("rprs.crc.ok", "Checksum correct")
f.auth_fresh = ProtoField.uint32("rprs.auth.fresh", "Freshness value carried by auth()",
                                 base.HEX)
f.auth_tag = ProtoField.uint32("rprs.auth.tag", "Tag carried by auth() (HMAC-SHA256, 4 bytes)",
                               base.HEX)
-- the analysis of a capture (as tcp.analysis.* does for TCP): the message a frame carries, its
-- sendings and its acknowledgement (docs/protocol.md clause 47), and what the air did to it
f.auth_ok = ProtoField.bool("rprs.auth.ok", "Tag correct under the ring key (preference)")
f.retrans = ProtoField.bool("rprs.analysis.retransmission", "Retransmission")
f.retrans_of = ProtoField.framenum("rprs.analysis.retransmission_of",
                                   "Retransmission of the message first sent in frame",
                                   base.NONE, frametype.REQUEST)
f.acked_in = ProtoField.framenum("rprs.analysis.acked_in", "Acknowledged in frame",
                                 base.NONE, frametype.ACK)
f.ack_rtt = ProtoField.relative_time("rprs.analysis.ack_rtt",
                                     "Time from the first sending to the acknowledgement")
f.acks = ProtoField.framenum("rprs.analysis.acks",
                             "Acknowledges the message sent in frame", base.NONE, frametype.ACK)
f.dup_ack = ProtoField.framenum("rprs.analysis.duplicate_ack",
                                "Duplicate acknowledgement: this robot acknowledged the message "
                                .. "in frame")
f.gap = ProtoField.relative_time("rprs.analysis.gap",
                                 "Time since the previous frame ended (to this one's start)")
f.early = ProtoField.bool("rprs.analysis.early",
                          "Sent before Ttrans had passed since the previous frame ended")
f.collided = ProtoField.bool("rprs.analysis.collided", "Collided with another transmission")
f.aborted = ProtoField.bool("rprs.analysis.aborted", "Cut short: the sender's radio died")
f.paused = ProtoField.bool("rprs.analysis.paused",
                           "Paused: the sender's transmit handler was late; the frame goes on "
                           .. "in its next packet")
f.continued = ProtoField.bool("rprs.analysis.continued", "Continued: the rest of a paused frame")

local e_header = ProtoExpert.new("rprs.header.bad", "No Header 0F 0A 05: garbage or a cut frame",
                                 expert.group.MALFORMED, expert.severity.ERROR)
local e_digit = ProtoExpert.new("rprs.digit.bad", "Not ASCII decimal digits",
                                expert.group.MALFORMED, expert.severity.ERROR)
local e_length = ProtoExpert.new("rprs.len.bad", "Length does not fit the frame's bytes",
                                 expert.group.MALFORMED, expert.severity.ERROR)
local e_end = ProtoExpert.new("rprs.end.bad", "End is not 17 19",
                              expert.group.MALFORMED, expert.severity.ERROR)
local e_crc = ProtoExpert.new("rprs.crc.bad", "crc() does not match the frame's bytes",
                              expert.group.CHECKSUM, expert.severity.ERROR)
local e_auth = ProtoExpert.new("rprs.auth.bad", "auth() tag does not match the ring key: "
                               .. "forged, or another ring's", expert.group.SECURITY,
                               expert.severity.ERROR)
local e_retrans = ProtoExpert.new("rprs.analysis.retransmission.expert",
                                  "Retransmission: this message was sent before",
                                  expert.group.SEQUENCE, expert.severity.WARN)
local e_early = ProtoExpert.new("rprs.analysis.early.expert",
                                "sent less than Ttrans after the previous frame ended: the "
                                .. "turn-taking guard broken", expert.group.SEQUENCE,
                                expert.severity.WARN)
local e_collided = ProtoExpert.new("rprs.analysis.collided.expert",
                                   "Collided: the air carried another transmission at once, "
                                   .. "so receivers heard garbage", expert.group.MALFORMED,
                                   expert.severity.ERROR)
local e_aborted = ProtoExpert.new("rprs.analysis.aborted.expert",
                                  "Cut short: the sender's radio died mid-frame",
                                  expert.group.MALFORMED, expert.severity.ERROR)
local e_piece = ProtoExpert.new("rprs.analysis.piece.expert",
                                "A piece of a frame its sender paused (its transmit handler "
                                .. "was late, the CPU model): the frame is this interface's "
                                .. "packets from the first paused to the last continued",
                                expert.group.SEQUENCE, expert.severity.NOTE)
rprs.experts = { e_header, e_digit, e_length, e_end, e_crc, e_auth, e_retrans, e_early,
                 e_collided, e_aborted, e_piece }

-- Preferences (Edit > Preferences > Protocols > RPRS; tshark -o rprs.NAME:VALUE)
rprs.prefs.check_crc = Pref.bool("Verify crc() checksums", true,
    "Compute CRC-16/CCITT-FALSE over Destination..Content and flag a crc() that differs "
    .. "(rprs.crc.computed, rprs.crc.ok); off, the carried value alone is shown")
rprs.prefs.auth_key = Pref.string("Ring key (authenticated profile)", "",
    "The ring key, 32 hex digits (a key file's key = line): each auth() tag is checked with "
    .. "it (rprs.auth.ok, rprs.auth.bad); empty, tags are shown, not checked")
rprs.prefs.ttrans_us = Pref.uint("Ttrans (us)", 5000,
    "The hand-over guard: a frame that starts sooner after the previous one ended is early "
    .. "(rprs.analysis.early); the paper's 5 ms")
rprs.prefs.tolerance_us = Pref.uint("Early-frame tolerance (us)", 500,
    "How much sooner than Ttrans a frame may start before it is called early (a bench's "
    .. "wall-clock stamps are late by up to a millisecond or so)")
rprs.prefs.analyze = Pref.bool("Analyse retransmissions, acknowledgements and hand-overs",
    true, "Mark each sending of a message after the first (rprs.analysis.retransmission), link "
    .. "messages and their acknowledgements (rprs.analysis.acked_in, ack_rtt, acks), and time "
    .. "each hand-over (rprs.analysis.gap, early)")

-- the packet comment the simulator and the hub write on a collided or cut transmission
local comment_field = Field.new("frame.comment")

-- MAC-layer commands (docs/protocol.md §4): a frame with nothing else carries no message
local mac_commands = { ack = true, crc = true, poll = true, ring = true, auth = true }

-- robot names for the Source and Destination columns
local function robot_name(id)
    if id == nil then return "?" end
    if id == 0 then return "father 0" end
    if id == 7 then return "all" end
    return "R" .. id
end

-- HMAC-SHA256 (FIPS 180-4, RFC 2104) on Lua 5.2's bit32, to check auth() tags with the ring
-- key given as a preference: Wireshark's Lua has no hash of its own. The round constants are
-- the first 32 bits of the fractional parts of the cube roots of the first 64 primes.
local band, bxor, bnot = bit32.band, bit32.bxor, bit32.bnot
local rrot, rsh = bit32.rrotate, bit32.rshift
local K256 = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2
}

local function sha256(msg)
    local h = { 0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19 }
    local bits = #msg * 8
    msg = msg .. "\128" .. string.rep("\0", (55 - #msg) % 64) .. string.char(0, 0, 0, 0,
        math.floor(bits / 16777216) % 256, math.floor(bits / 65536) % 256,
        math.floor(bits / 256) % 256, bits % 256)
    local w = {}
    for i = 1, #msg, 64 do
        for j = 1, 16 do
            local a, b, c, d = msg:byte(i + 4 * j - 4, i + 4 * j - 1)
            w[j] = ((a * 256 + b) * 256 + c) * 256 + d
        end
        for j = 17, 64 do
            local x, y = w[j - 15], w[j - 2]
            local s0 = bxor(rrot(x, 7), rrot(x, 18), rsh(x, 3))
            local s1 = bxor(rrot(y, 17), rrot(y, 19), rsh(y, 10))
            w[j] = band(w[j - 16] + s0 + w[j - 7] + s1, 0xffffffff)
        end
        local a, b, c, d, e, f, g, hh = h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]
        for j = 1, 64 do
            local S1 = bxor(rrot(e, 6), rrot(e, 11), rrot(e, 25))
            local ch = bxor(band(e, f), band(bnot(e), g))
            local t1 = hh + S1 + ch + K256[j] + w[j]
            local S0 = bxor(rrot(a, 2), rrot(a, 13), rrot(a, 22))
            local maj = bxor(band(a, b), band(a, c), band(b, c))
            hh, g, f, e, d, c, b, a = g, f, e, band(d + t1, 0xffffffff), c, b, a,
                                      band(t1 + S0 + maj, 0xffffffff)
        end
        h[1], h[2], h[3], h[4] = band(h[1] + a, 0xffffffff), band(h[2] + b, 0xffffffff),
                                 band(h[3] + c, 0xffffffff), band(h[4] + d, 0xffffffff)
        h[5], h[6], h[7], h[8] = band(h[5] + e, 0xffffffff), band(h[6] + f, 0xffffffff),
                                 band(h[7] + g, 0xffffffff), band(h[8] + hh, 0xffffffff)
    end
    local out = {}
    for j = 1, 8 do
        local v = h[j]
        out[j] = string.char(math.floor(v / 16777216) % 256, math.floor(v / 65536) % 256,
                             math.floor(v / 256) % 256, v % 256)
    end
    return table.concat(out)
end

local function hmac_sha256_hex(key, msg)
    key = key .. string.rep("\0", 64 - #key)
    local ipad = key:gsub(".", function(ch) return string.char(bxor(ch:byte(), 0x36)) end)
    local opad = key:gsub(".", function(ch) return string.char(bxor(ch:byte(), 0x5c)) end)
    local digest = sha256(opad .. sha256(ipad .. msg))
    return (digest:gsub(".", function(ch) return string.format("%02x", ch:byte()) end))
end

-- a generated check of ``range`` into ``field``; failed, its expert info ``e``: the text the
-- Info column gets (" [mark]" when it failed)
local function verdict(t, field, range, good, e, mark)
    local item = t:add(field, range, good)
    item:set_generated()
    if good then return "" end
    item:add_proto_expert_info(e)
    return " [" .. mark .. "]"
end

-- the ring key from the preference: 32 hex digits (a key file's key = line), else nil
local function ring_key()
    local hex = rprs.prefs.auth_key or ""
    hex = hex:gsub("%s", ""):lower()
    if not hex:match("^" .. string.rep("%x", 32) .. "$") then return nil end
    return (hex:gsub("%x%x", function(xx) return string.char(tonumber(xx, 16)) end))
end

-- per capture, filled on the first pass: message key -> its first sending (frame, time);
-- (src, num) -> that first sending; frame -> the first sending it repeats; (src, num) -> the
-- first frame that acknowledged it; frame -> the (src, num) it acknowledges. A field that
-- looks ahead (acknowledged in) needs a second pass: tshark -2, or the GUI
local first_sent, sent_as, repeats, acked, ack_of = {}, {}, {}, {}, {}
-- frame -> seconds from the previous radio frame's end to its start; the last frame's end
local gaps, last_end = {}, nil
-- "(src, num) > acknowledging robot" -> its first acknowledging frame; frame -> those it repeats
local acked_by, dup_acks = {}, {}
function rprs.init()
    first_sent, sent_as, repeats, acked, ack_of = {}, {}, {}, {}, {}
    gaps, last_end = {}, nil
    acked_by, dup_acks = {}, {}
end

-- a byte on air, seconds: the father PC's UART at 9600 exactly, a child's MB90F549 at
-- 16 MHz / 1664 a bit (docs/protocol.md clause 3)
local function byte_time(src)
    if src == 0 then return 10 / 9600 end
    return 16640 / 16e6
end

-- CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR), protocol clause 20
local function crc16(bytes)
    local crc = 0xFFFF
    for i = 0, bytes:len() - 1 do
        crc = bit32.bxor(crc, bit32.lshift(bytes:get_index(i), 8))
        for _ = 1, 8 do
            if bit32.band(crc, 0x8000) ~= 0 then
                crc = bit32.band(bit32.bxor(bit32.lshift(crc, 1), 0x1021), 0xFFFF)
            else
                crc = bit32.band(bit32.lshift(crc, 1), 0xFFFF)
            end
        end
    end
    return crc
end

-- A field of ASCII decimal digits (protocol clause 3.1). One that is not gets no value, so
-- a display filter on the field (rprs.type == 0) does not match it: a text item and the
-- expert info rprs.digit.bad name its first bad byte, and the caller shows "?".
local function number(tvb, offset, width, tree, field, label)
    local range = tvb(offset, width)
    local text = range:string()
    if text:match("^%d+$") then
        local value = tonumber(text)
        tree:add(field, range, value)
        return value
    end
    local bytes = range:bytes()
    local at, byte = 0, bytes:get_index(0)
    for i = 0, width - 1 do
        local b = bytes:get_index(i)
        if b < 0x30 or b > 0x39 then at, byte = i, b; break end
    end
    local shown = (byte >= 0x20 and byte < 0x7f) and string.format("0x%02x '%c'", byte, byte)
                  or string.format("0x%02x", byte)
    local what = string.format("%s: byte %d of %d, %s, is not an ASCII decimal digit", label,
                               at + 1, width, shown)
    tree:add(range, string.format("%s: bytes %s, not ASCII decimal digits (no value)", label,
                                  bytes:tohex()))
        :add_proto_expert_info(e_digit, what)
    return nil
end

-- The capture's own word on a packet (its comment: "collided", "aborted: ..."), marked on
-- every packet, a frame or not: in the analysis subtree ``a`` (made under ``t`` if nil);
-- returns ``info`` prefixed.
local function mark_comment(tvb, t, info, a)
    local comment = comment_field()
    if comment == nil then return info end
    local text = tostring(comment.value)
    for _, mark in ipairs({ { "continued", f.continued, e_piece, "[continued] " },
                            { "collided", f.collided, e_collided, "[collided] " },
                            { "aborted", f.aborted, e_aborted, "[cut short] " },
                            { "paused", f.paused, e_piece, "[paused] " } }) do
        if text:find(mark[1]) then
            a = a or t:add(rprs, tvb(), "Analysis")
            local item = a:add(mark[2], true)
            item:set_generated()
            item:add_proto_expert_info(mark[3])
            info = mark[4] .. info
        end
    end
    return info
end

function rprs.dissector(tvb, pinfo, tree)
    local n = tvb:len()
    pinfo.cols.protocol = "RPRS"
    local t = tree:add(rprs, tvb(), "RPRS radio frame")
    if n == 0 then
        -- a transmission whose sender's radio died before its first byte (the capture keeps
        -- the packet, and says so in its comment)
        pinfo.cols.info = mark_comment(tvb, t, "no byte sent")
        return 0
    end
    local comment = comment_field()
    local text = comment ~= nil and tostring(comment.value) or ""
    if text:find("paused") or text:find("continued") then
        -- a piece of a frame sent with gaps (the capture's comment says so): its bytes are
        -- the frame's, in pieces; none of them is malformed for being a piece
        t:add(f.content, tvb())
        pinfo.cols.info = mark_comment(tvb, t, string.format("piece of a paused frame "
                                                             .. "(%d bytes)", n))
        return n
    end
    if n < 3 or tvb(0, 3):bytes():tohex() ~= "0F0A05" then
        t:add_proto_expert_info(e_header)
        pinfo.cols.info = mark_comment(tvb, t, string.format("not a frame (%d bytes)", n))
        return n
    end
    if n < 14 then
        -- a Header, then fewer bytes than the shortest frame: a frame cut short (its sender's
        -- radio died, an aborted packet); the fields it has are read, as rprs decode does
        t:add(f.header, tvb(0, 3))
        local fields = { { 3, 1, f.dst, "Destination" }, { 4, 1, f.src, "Source" },
                         { 5, 2, f.num, "Number" }, { 7, 1, f.type, "Type" },
                         { 8, 4, f.len, "Length" } }
        for _, fd in ipairs(fields) do
            if fd[1] + fd[2] <= n then number(tvb, fd[1], fd[2], t, fd[3], fd[4]) end
        end
        t:add_proto_expert_info(e_length, string.format(
            "Cut short: %d bytes, a frame has at least 14", n))
        pinfo.cols.info = mark_comment(tvb, t, string.format(
            "cut short after %d of at least 14 bytes", n))
        return n
    end
    t:add(f.header, tvb(0, 3))
    local dst = number(tvb, 3, 1, t, f.dst, "Destination")
    local src = number(tvb, 4, 1, t, f.src, "Source")
    local num = number(tvb, 5, 2, t, f.num, "Number")
    local typ = number(tvb, 7, 1, t, f.type, "Type")
    local len = number(tvb, 8, 4, t, f.len, "Length")
    local info = string.format("%s -> %s #%s %s", src or "?", dst or "?", num or "?",
                               type_names[typ] or ("type " .. (typ or "?")))
    pinfo.cols.src = robot_name(src)
    pinfo.cols.dst = robot_name(dst)
    local app = {}          -- the application commands: the message this frame carries
    local clen = len
    if len == nil or 12 + len + 2 > n then
        t:add_proto_expert_info(e_length)
        clen = n - 12
    end
    local crange = clen > 0 and tvb(12, clen) or nil
    if crange then
        local ct = t:add(f.content, crange)
        local content = crange:string()
        local pos = 1
        while true do
            local s, e, name, args = content:find("(%a+)%(([^)]*)%)", pos)
            if not s then break end
            local item = ct:add(f.cmd, tvb(12 + s - 1, e - s + 1), name)
            item:add(f.args, tvb(12 + s - 1 + #name + 1, #args > 0 and #args or 0), args)
            info = info .. " " .. name .. "(" .. args .. ")"
            if not mac_commands[name] then
                app[#app + 1] = name .. "(" .. args .. ")"
            elseif name == "ack" and not pinfo.visited then
                local a_src, a_num = args:match("^(%d+),(%d+)$")
                if a_src then
                    local k = tonumber(a_src) .. ":" .. tonumber(a_num)
                    if acked[k] == nil then
                        acked[k] = { frame = pinfo.number, time = pinfo.abs_ts }
                    end
                    ack_of[pinfo.number] = ack_of[pinfo.number] or {}
                    table.insert(ack_of[pinfo.number], k)
                    -- the same robot acknowledging the same message again
                    local by = k .. ">" .. tostring(src)
                    if acked_by[by] == nil then
                        acked_by[by] = pinfo.number
                    elseif acked_by[by] ~= pinfo.number then
                        dup_acks[pinfo.number] = dup_acks[pinfo.number] or {}
                        table.insert(dup_acks[pinfo.number], acked_by[by])
                    end
                end
            end
            pos = e + 1
        end
        -- the checksum extension: crc(NNNNN) ends Content and covers Destination up to the
        -- last Content byte before it
        local digits = content:match("crc%((%d%d%d%d%d)%)$")
        if digits and len ~= nil and clen == len then
            local carried = tonumber(digits)
            local crange = tvb(12 + clen - 10, 10)
            t:add(f.crc, crange, carried)
            if rprs.prefs.check_crc then
                local computed = crc16(tvb:bytes(3, 9 + clen - 10))
                t:add(f.crc_calc, crange, computed):set_generated()
                info = info .. verdict(t, f.crc_ok, crange, carried == computed, e_crc, "bad crc")
            end
        end
        -- the authenticated profile (protocol clause 52): auth(FFFFFFFF,TTTTTTTT) ends Content,
        -- 8 lowercase hex digits each; the tag is checked when the ring key is a preference
        local fresh, tag = content:match("auth%(([0-9a-f]+),([0-9a-f]+)%)$")
        if fresh and #fresh == 8 and #tag == 8 and len ~= nil and clen == len then
            t:add(f.auth_fresh, tvb(12 + clen - 18, 8), tonumber(fresh, 16))
            t:add(f.auth_tag, tvb(12 + clen - 9, 8), tonumber(tag, 16))
            local key = ring_key()
            if key ~= nil then
                -- the tag covers Destination up to the comma after the freshness value
                local want = hmac_sha256_hex(key, tvb:raw(3, clen)):sub(1, 8)
                info = info .. verdict(t, f.auth_ok, tvb(12 + clen - 9, 8), want == tag, e_auth,
                                       "bad tag")
            end
        end
    end
    if len ~= nil and 12 + len + 2 <= n then
        local erange = tvb(12 + len, 2)
        local item = t:add(f.endmark, erange)
        if erange:bytes():tohex() ~= "1719" then
            item:add_proto_expert_info(e_end)
        end
        if 12 + len + 2 < n then
            t:add_proto_expert_info(e_length, "bytes after End")
        end
    end
    -- the analysis: retransmissions and acknowledgements of the message (src, num)
    local a = t:add(rprs, tvb(), "Analysis")
    a:set_generated()
    if src ~= nil and num ~= nil and #app > 0 and rprs.prefs.analyze then
        local key = src .. ":" .. (dst or "?") .. ":" .. num .. ":" .. (typ or "?") .. ":" ..
                    table.concat(app)
        if not pinfo.visited then
            local first = first_sent[key]
            if first == nil then
                first_sent[key] = { frame = pinfo.number, time = pinfo.abs_ts }
                sent_as[src .. ":" .. num] = first_sent[key]
            elseif first.frame ~= pinfo.number then
                repeats[pinfo.number] = first
            end
        end
        local first = repeats[pinfo.number]
        if first ~= nil then
            a:add(f.retrans, true):set_generated()
            local item = a:add(f.retrans_of, first.frame)
            item:set_generated()
            item:add_proto_expert_info(e_retrans)
            info = "[retransmission] " .. info
        end
        local ack = acked[src .. ":" .. num]
        local sent = first or first_sent[key]
        if ack ~= nil and sent ~= nil and ack.frame > pinfo.number then
            a:add(f.acked_in, ack.frame):set_generated()
            if first == nil then
                local d = ack.time - sent.time
                local whole = math.floor(d)
                a:add(f.ack_rtt, NSTime.new(whole, math.floor((d - whole) * 1e9 + 0.5)))
                    :set_generated()
            end
        end
    end
    for _, k in ipairs(rprs.prefs.analyze and ack_of[pinfo.number] or {}) do
        local sent = sent_as[k]
        if sent ~= nil and sent.frame < pinfo.number then
            a:add(f.acks, sent.frame):set_generated()
        end
    end
    for _, first in ipairs(rprs.prefs.analyze and dup_acks[pinfo.number] or {}) do
        a:add(f.dup_ack, first):set_generated()
    end
    if rprs.prefs.analyze and dup_acks[pinfo.number] ~= nil then
        info = "[dup ack] " .. info
    end
    -- the hand-over: from the previous frame's end (packets are stamped at their last stop
    -- bit) to this one's first bit
    if not pinfo.visited then
        local t = pinfo.abs_ts
        if last_end ~= nil then
            gaps[pinfo.number] = t - n * byte_time(src) - last_end
        end
        last_end = t
    end
    local gap = gaps[pinfo.number]
    if gap ~= nil and rprs.prefs.analyze then
        local whole = math.floor(gap)
        a:add(f.gap, NSTime.new(whole, math.floor((gap - whole) * 1e9 + 0.5))):set_generated()
        if gap < (rprs.prefs.ttrans_us - rprs.prefs.tolerance_us) / 1e6 then
            local item = a:add(f.early, true)
            item:set_generated()
            item:add_proto_expert_info(e_early)
            info = "[early] " .. info
        end
    end
    pinfo.cols.info = mark_comment(tvb, t, info, a)
    return n
end

local encaps = wtap_encaps or wtap
DissectorTable.get("wtap_encap"):add(encaps.USER0, rprs)

-- Statistics ------------------------------------------------------------------------------
-- Per robot (endpoints) and per Source -> Destination pair (conversations) of the radio
-- frames: tshark -q -z rprs,robots and -z rprs,conv; in the GUI, Statistics > RPRS.
local x_src, x_dst = Field.new("rprs.src"), Field.new("rprs.dst")
local x_retrans, x_collided = Field.new("rprs.analysis.retransmission"),
                              Field.new("rprs.analysis.collided")

local function median(v)
    if #v == 0 then return nil end
    table.sort(v)
    return v[math.floor(#v / 2) + 1]
end

local function ms(x) return x and string.format("%.1f", x * 1000) or "-" end

-- a tap on the radio frames; report(robots, pairs) gives the text when the capture is read
local function frame_tap(report, show)
    local robots, pairs_ = {}, {}
    local tap = Listener.new(nil, "rprs")
    function tap.reset() robots, pairs_ = {}, {} end
    function tap.packet(pinfo, tvb)
        local src, dst = x_src(), x_dst()
        if src == nil then return end
        src = src.value
        local r = robots[src] or { frames = 0, bytes = 0, to = 0, retrans = 0, collided = 0,
                                   gaps = {}, last = nil }
        robots[src] = r
        r.frames = r.frames + 1
        r.bytes = r.bytes + tvb:len()
        if x_retrans() ~= nil then r.retrans = r.retrans + 1 end
        if x_collided() ~= nil then r.collided = r.collided + 1 end
        local t = pinfo.abs_ts
        if r.last ~= nil then table.insert(r.gaps, t - r.last) end
        r.last = t
        if dst ~= nil then
            dst = dst.value
            local d = robots[dst] or { frames = 0, bytes = 0, to = 0, retrans = 0,
                                       collided = 0, gaps = {}, last = nil }
            robots[dst] = d
            d.to = d.to + 1
            local k = src .. ">" .. dst
            local c = pairs_[k] or { src = src, dst = dst, frames = 0, bytes = 0,
                                     first = t, last = t }
            pairs_[k] = c
            c.frames, c.bytes, c.last = c.frames + 1, c.bytes + tvb:len(), t
        end
    end
    function tap.draw() show(report(robots, pairs_)) end
    return tap
end

local function sorted_keys(t, less)
    local keys = {}
    for k in pairs(t) do table.insert(keys, k) end
    table.sort(keys, less)
    return keys
end

local function robots_report(robots)
    local lines = { "RPRS robots (endpoints): frames each robot sent, and to it",
        string.format("%-9s %7s %8s %7s %8s %9s %12s", "robot", "frames", "bytes", "to it",
                      "retrans", "collided", "turn ms p50") }
    for _, id in ipairs(sorted_keys(robots)) do
        local r = robots[id]
        lines[#lines + 1] = string.format("%-9s %7d %8d %7d %8d %9d %12s", robot_name(id),
            r.frames, r.bytes, r.to, r.retrans, r.collided, ms(median(r.gaps)))
    end
    return table.concat(lines, "\n")
end

local function conv_report(_, pairs_)
    local lines = { "RPRS conversations: frames from Source to Destination",
        string.format("%-9s %-9s %7s %8s %10s %10s", "source", "dest", "frames", "bytes",
                      "first s", "last s") }
    local first
    for _, c in pairs(pairs_) do
        if first == nil or c.first < first then first = c.first end
    end
    local keys = sorted_keys(pairs_, function(a, b)
        local x, y = pairs_[a], pairs_[b]
        if x.src ~= y.src then return x.src < y.src end
        return x.dst < y.dst
    end)
    for _, k in ipairs(keys) do
        local c = pairs_[k]
        lines[#lines + 1] = string.format("%-9s %-9s %7d %8d %10.3f %10.3f", robot_name(c.src),
            robot_name(c.dst), c.frames, c.bytes, c.first - first, c.last - first)
    end
    return table.concat(lines, "\n")
end

for name, report in pairs({ robots = robots_report, conv = conv_report }) do
    register_stat_cmd_arg("rprs," .. name, function()
        frame_tap(function(robots, pairs_) return report(robots, pairs_) end,
                  function(text) print(text) end)
    end)
    if gui_enabled() then
        register_menu("RPRS/" .. (name == "robots" and "Robots" or "Conversations"), function()
            local win = TextWindow.new("RPRS " .. name)
            local tap = frame_tap(report, function(text) win:set(text) end)
            win:set_atclose(function() tap:remove() end)
            retap_packets()
        end, MENU_STAT_UNSORTED)
    end
end

-- CAN payloads ---------------------------------------------------------------------------
-- Each identifier of can_bus/rprs.dbc is registered in Wireshark's can.id table; the payload
-- is decoded signal by signal: physical value = raw * scale + offset, with the unit and the
-- value name. Fields: rprs_can.msg, rprs_can.sender, rprs_can.<message>.<signal> (lower case).

-- BEGIN DBC TABLE (generated from can_bus/rprs.dbc by python -m hil.wireshark.dbc_table)
local dbc_messages = {
  [0x010] = { name = "ESTOP", sender = "MCU", dlc = 1, signals = {
      { name = "reason", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x0c1] = { name = "EVENT1", sender = "JOINT1", dlc = 3, signals = {
      { name = "kind", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [1] = "done", [2] = "fault", [3] = "refused" } },
      { name = "seq", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "code", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "none", [1] = "stalled(fault)/out_of_range(refused)", [2] = "limit(fault)/busy(refused)", [3] = "overcurrent(fault)/faulted(refused)" } },
  } },
  [0x0c2] = { name = "EVENT2", sender = "JOINT2", dlc = 3, signals = {
      { name = "kind", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [1] = "done", [2] = "fault", [3] = "refused" } },
      { name = "seq", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "code", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "none", [1] = "stalled(fault)/out_of_range(refused)", [2] = "limit(fault)/busy(refused)", [3] = "overcurrent(fault)/faulted(refused)" } },
  } },
  [0x0c3] = { name = "EVENT3", sender = "JOINT3", dlc = 3, signals = {
      { name = "kind", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [1] = "done", [2] = "fault", [3] = "refused" } },
      { name = "seq", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "code", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "none", [1] = "stalled(fault)/out_of_range(refused)", [2] = "limit(fault)/busy(refused)", [3] = "overcurrent(fault)/faulted(refused)" } },
  } },
  [0x0c4] = { name = "EVENT4", sender = "JOINT4", dlc = 3, signals = {
      { name = "kind", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [1] = "done", [2] = "fault", [3] = "refused" } },
      { name = "seq", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "code", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "none", [1] = "stalled(fault)/out_of_range(refused)", [2] = "limit(fault)/busy(refused)", [3] = "overcurrent(fault)/faulted(refused)" } },
  } },
  [0x0c5] = { name = "EVENT5", sender = "WHEEL", dlc = 3, signals = {
      { name = "kind", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [1] = "done", [2] = "fault", [3] = "refused" } },
      { name = "seq", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "code", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "none", [1] = "stalled(fault)/out_of_range(refused)", [2] = "limit(fault)/busy(refused)", [3] = "overcurrent(fault)/faulted(refused)" } },
  } },
  [0x0c6] = { name = "EVENT6", sender = "PAW", dlc = 3, signals = {
      { name = "kind", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [1] = "done", [2] = "fault", [3] = "refused" } },
      { name = "seq", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "code", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "none", [1] = "stalled(fault)/out_of_range(refused)", [2] = "limit(fault)/busy(refused)", [3] = "overcurrent(fault)/faulted(refused)" } },
  } },
  [0x101] = { name = "JOINT1_CMD", sender = "MCU", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = false, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "seq", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "mode", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "move", [1] = "hold", [2] = "relax" } },
  } },
  [0x102] = { name = "JOINT2_CMD", sender = "MCU", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = false, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "seq", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "mode", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "move", [1] = "hold", [2] = "relax" } },
  } },
  [0x103] = { name = "JOINT3_CMD", sender = "MCU", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = false, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "seq", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "mode", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "move", [1] = "hold", [2] = "relax" } },
  } },
  [0x104] = { name = "JOINT4_CMD", sender = "MCU", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = false, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "seq", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
      { name = "mode", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "move", [1] = "hold", [2] = "relax" } },
  } },
  [0x105] = { name = "WHEEL_CMD", sender = "MCU", dlc = 7, signals = {
      { name = "speed", byte = 0, size = 2, signed = true, scale = 1, offset = 0, unit = "mm/s" },
      { name = "distance", byte = 2, size = 4, signed = true, scale = 1, offset = 0, unit = "mm" },
      { name = "seq", byte = 6, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x106] = { name = "PAW_CMD", sender = "MCU", dlc = 3, signals = {
      { name = "action", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "close", [1] = "open" } },
      { name = "force", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "%" },
      { name = "seq", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x181] = { name = "JOINT1_STATUS", sender = "JOINT1", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = true, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "state", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "idle", [1] = "moving", [2] = "holding", [3] = "stalled", [4] = "fault" } },
      { name = "seq", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x182] = { name = "JOINT2_STATUS", sender = "JOINT2", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = true, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "state", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "idle", [1] = "moving", [2] = "holding", [3] = "stalled", [4] = "fault" } },
      { name = "seq", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x183] = { name = "JOINT3_STATUS", sender = "JOINT3", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = true, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "state", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "idle", [1] = "moving", [2] = "holding", [3] = "stalled", [4] = "fault" } },
      { name = "seq", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x184] = { name = "JOINT4_STATUS", sender = "JOINT4", dlc = 6, signals = {
      { name = "angle", byte = 0, size = 2, signed = true, scale = 0.01, offset = 0, unit = "deg" },
      { name = "speed", byte = 2, size = 2, signed = true, scale = 0.1, offset = 0, unit = "deg/s" },
      { name = "state", byte = 4, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "idle", [1] = "moving", [2] = "holding", [3] = "stalled", [4] = "fault" } },
      { name = "seq", byte = 5, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x185] = { name = "WHEEL_STATUS", sender = "WHEEL", dlc = 8, signals = {
      { name = "speed", byte = 0, size = 2, signed = true, scale = 1, offset = 0, unit = "mm/s" },
      { name = "odometer", byte = 2, size = 4, signed = true, scale = 1, offset = 0, unit = "mm" },
      { name = "state", byte = 6, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "idle", [1] = "moving", [2] = "holding", [3] = "stalled", [4] = "fault" } },
      { name = "seq", byte = 7, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
  [0x186] = { name = "PAW_STATUS", sender = "PAW", dlc = 4, signals = {
      { name = "opening", byte = 0, size = 1, signed = false, scale = 1, offset = 0, unit = "%" },
      { name = "grip", byte = 1, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "empty", [1] = "holding" } },
      { name = "state", byte = 2, size = 1, signed = false, scale = 1, offset = 0, unit = "", choices = { [0] = "idle", [1] = "moving", [2] = "holding", [3] = "stalled", [4] = "fault" } },
      { name = "seq", byte = 3, size = 1, signed = false, scale = 1, offset = 0, unit = "" },
  } },
}
-- END DBC TABLE
local rcan = Proto("rprs_can", "RPRS CAN payload (rprs.dbc)")
local cf = rcan.fields
cf.msg = ProtoField.string("rprs_can.msg", "Message")
cf.sender = ProtoField.string("rprs_can.sender", "Sender")
local sig_fields = {}
for id, m in pairs(dbc_messages) do
    sig_fields[id] = {}
    for i, s in ipairs(m.signals) do
        local key = m.name:lower() .. "." .. s.name
        local label = s.name .. (s.unit ~= "" and (" (" .. s.unit .. ")") or "")
        local fld
        if s.choices and s.scale == 1 and s.offset == 0 then
            -- an enumeration: an integer field with its value names, so that a filter may
            -- name the value (rprs_can.status1.state == "idle")
            fld = (s.signed and ProtoField.int32 or ProtoField.uint32)(
                "rprs_can." .. key, label, base.DEC, s.choices)
            s.enum = true
        else
            fld = ProtoField.double("rprs_can." .. key, label)
        end
        sig_fields[id][i] = fld
        cf[key] = fld
    end
end
local e_dlc = ProtoExpert.new("rprs_can.dlc.bad", "Payload length is not the DBC's DLC",
                              expert.group.MALFORMED, expert.severity.ERROR)
rcan.experts = { e_dlc }

function rcan.dissector(tvb, pinfo, tree)
    local id = pinfo.match_uint
    local m = dbc_messages[id]
    if m == nil then return 0 end
    local n = tvb:len()
    local t = tree:add(rcan, tvb(), "RPRS CAN " .. m.name)
    t:add(cf.msg, tvb(0, 0), m.name):set_generated()
    t:add(cf.sender, tvb(0, 0), m.sender):set_generated()
    if n ~= m.dlc then t:add_proto_expert_info(e_dlc) end
    local parts = {}
    for i, s in ipairs(m.signals) do
        if s.byte + s.size <= n then
            local r = tvb(s.byte, s.size)
            local raw = s.signed and r:le_int() or r:le_uint()
            local v = raw * s.scale + s.offset
            local text = string.format("%g", v)
            local name = s.choices and s.choices[raw]
            local shown = text .. (s.unit ~= "" and (" " .. s.unit) or "") ..
                          (name and (" (" .. name .. ")") or "")
            if s.enum then
                t:add(sig_fields[id][i], r, raw):set_text(s.name .. ": " .. shown)
            else
                t:add(sig_fields[id][i], r, v):set_text(s.name .. ": " .. shown)
            end
            parts[#parts + 1] = s.name .. "=" .. (name or text)
        end
    end
    pinfo.cols.protocol = "RPRS CAN"
    pinfo.cols.info = m.name .. " " .. table.concat(parts, " ")
    return n
end

local can_ids = DissectorTable.get("can.id")
for id, _ in pairs(dbc_messages) do
    can_ids:add(id, rcan)
end
